"""A scene's sensor signals under each interface model, and the choice of the model a scene requires.

Models (docs/scenes.md, "Interface models"; docs/theory.md 4c):

- ``"exact"``: every frame's contact solved (:func:`.scene_contact.solve_scan`, warm-started);
- ``"linear"``: the superposition of full contact, clipped at 0 (:meth:`.SceneFrames.tractions`);
- ``"modulation"``: docs/theory.md 4b's M = 1 + h / h_ref.

``"auto"`` (:func:`choose_model`) estimates each cheap model's error BEFORE simulating, from the
surface's full-contact pressure ``E* |k| H~ / 2`` against the contact's pressure (the tension the
linear model cannot carry, read at the sensors; and, where the texture has a period, the contact
room's periodic-cell estimate :func:`tactilab.forward.interface_model_errors`, the larger of the
two), confirms it on a few frames solved exactly, and picks the cheapest model whose error is
within the scene's ``tol``.

Error (:func:`signal_error`): max over the scan of |error| / max |signal|, per sensor and component,
then the largest over the sensors and components; a component whose signal is below 1e-3 of its
array's largest is measured against that floor (a signal that vanishes by symmetry has no
relative error).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .contact import interface_model_errors
from .scene_contact import solve_scan
from .scene_frames import CELL_NODES, SceneFrames
from .scene_layered import refuse_layered_modulation

#: cheapest first: auto picks the first whose error is within tol
CHEAP_FIRST = ("modulation", "linear", "exact")
#: frames the a-priori criterion looks at, and frames solved exactly to confirm it
APRIORI_FRAMES = 16
CHECK_FRAMES = 3
#: the a-priori estimate's safety factor over the clipped tension's signal (the exact contact
#: moves that load to the neighbouring nodes: the error is up to about the tension itself)
APRIORI_FACTOR = 2.0
#: the error measured on the few frames solved exactly, times this, stands for the frames not solved
POSTERIORI_FACTOR = 2.0
#: the exact model's contact tolerance (solve_contact's relative gap residual) per unit of the scene's
#: tol: on the benchmark scene a residual of 1e-6 moves the signal by 2.5e-4 of it, 1e-5 by 3.9e-3
CONTACT_TOL_PER_TOL = 1e-4
#: signals below this fraction of their array's largest are measured against the floor
SIGNAL_FLOOR = 1e-3


def signal_error(approx: np.ndarray, exact: np.ndarray) -> float:
    """The scene's error measure: max over the scan of |approx - exact| / max |exact| (per sensor and
    component, floored at 1e-3 of the largest), the largest over sensors and components.

    Parameters
    ----------
    approx, exact : ndarray, shape (n_frames, n_sensors, n_components)
    """
    a, e = np.asarray(approx, float), np.asarray(exact, float)
    if a.shape != e.shape:
        raise ValueError(f"approx: shape {a.shape} differs from exact {e.shape}; compare the same frames and sensors")
    scale = np.abs(e).max(axis=0)
    scale = np.maximum(scale, SIGNAL_FLOOR * max(float(scale.max()), 1e-300))
    return float((np.abs(a - e).max(axis=0) / scale).max())


@dataclass
class ModelRun:
    """Sensor signals of one model over a scene's frames.

    Attributes
    ----------
    model : str
    values : ndarray, shape (n_frames, n_sensors, n_components)
        Pa (stress) or tensor strain.
    frames : ndarray of int
        The frames computed.
    seconds : float
        Wall time, s.
    iterations : ndarray or None
        The exact model's contact iterations per frame.
    """

    model: str
    values: np.ndarray
    frames: np.ndarray
    seconds: float
    iterations: np.ndarray | None = None
    contact_fraction: np.ndarray | None = None


def run_model(frames: SceneFrames, model: str, indices=None, *, warm_start: bool = True, batch: int = 64,
              progress: bool = False) -> ModelRun:
    """The sensor signals of ``model`` at the frames ``indices`` (default all) of ``frames``.

    The exact model solves each contact to the relative gap residual ``1e-4 * tol`` (the scene's
    ``tol``; at most 1e-6, at least 1e-10).
    """
    if model not in ("exact", "linear", "modulation"):
        raise ValueError(f"model: must be 'exact', 'linear' or 'modulation' here ('auto' is choose_model), got {model!r}")
    idx = np.arange(frames.n_frames) if indices is None else np.asarray(indices, dtype=int)
    readout = frames.readout()
    t0 = time.perf_counter()
    if model == "exact":
        consecutive = idx.size > 1 and np.all(np.diff(idx) == 1)
        shifts = frames.shifts[idx] if (frames.shifts is not None and consecutive) else None
        sol = solve_scan(frames.skin, lambda k: frames.gap(int(idx[k])), frames.spacing, n_frames=idx.size,
                         periodic=frames.periodic, friction=frames.friction,
                         slide_direction=(frames.direction, 0.0), slip_ratio=frames.slip_ratios[idx],
                         shifts=shifts, warm_start=warm_start and consecutive, sensors=readout,
                         keep_tractions=False, progress=progress, tol=contact_tol(frames), **frames.load)
        return ModelRun(model, sol.outputs[0], idx, time.perf_counter() - t0, sol.iterations, sol.contact_fraction)
    out = np.empty((idx.size, readout.n_outputs))
    for start in range(0, idx.size, batch):
        chunk = idx[start:start + batch]
        tr = [frames.tractions(model, int(i)) for i in chunk]
        qy = None if tr[0][2] is None else np.stack([t[2] for t in tr])
        out[start:start + chunk.size] = readout.apply(readout.stack(np.stack([t[0] for t in tr]),
                                                                    np.stack([t[1] for t in tr]), qy))
    return ModelRun(model, readout.split(out)[0], idx, time.perf_counter() - t0)


def contact_tol(frames: SceneFrames) -> float:
    """The exact model's contact tolerance for the scene's ``tol`` (:data:`CONTACT_TOL_PER_TOL`)."""
    return float(min(1e-6, max(1e-10, CONTACT_TOL_PER_TOL * frames.scene.contact.tol)))


def apriori_errors(frames: SceneFrames, indices, *, per_frame: bool = False):
    """Each cheap model's error estimated without a contact solve, and the contact's pressure ratio.

    Linear: the tension ``t = max(0, -(p_finger + E* |k| H~ / 2))`` that the clipped superposition
    drops is the load the exact contact moves elsewhere; its signal at the sensors, times
    ``APRIORI_FACTOR``, over the scene's signal. Modulation: the signal of the difference between the
    modulation's and the linear model's tractions, plus the linear model's error.

    Returns
    -------
    errors : dict
        ``{"linear": float, "modulation": float}`` (a layered skin: linear only).
    pressures : dict
        ``"p_bar"`` (the contact's mean pressure, Pa), ``"p_star"`` (the largest tension of the
        texture's full-contact pressure, Pa: pi E* A / L for a sinusoid) and ``"ratio"`` p_bar / p_star.
    frame_errors : ndarray, shape (len(indices),)
        With ``per_frame``: the two estimates summed, frame by frame (where to confirm them).
    """
    readout = frames.readout()
    lin, mod, tension, p_star = [], [], [], 0.0
    for i in indices:
        p_lin, q_lin, qy = frames.tractions("linear", int(i))
        p_mod, q_mod, _ = (p_lin, q_lin, None) if frames.layered else frames.tractions("modulation", int(i))
        tex = frames.texture_pressure(int(i))
        if frames.periodic:
            base, inside = np.full(frames.shape, frames.mean_pressure), np.ones(frames.shape, bool)
        else:
            base = frames._finger_tractions(1.0, fingerprint=False)[0]
            inside = base > 0
        t = np.where(inside, np.maximum(-(base + tex), 0.0), 0.0)
        p_star = max(p_star, float(np.max(-tex[inside], initial=0.0)))
        zero = None if qy is None else np.zeros(frames.shape)
        lin.append((p_lin, q_lin, zero))
        mod.append((p_mod, q_mod, zero))
        tension.append((t, frames.direction * frames.friction * t, zero))
    read = {name: _read(readout, rows) for name, rows in (("linear", lin), ("modulation", mod), ("tension", tension))}
    scale = np.maximum(np.abs(read["linear"]).max(axis=0), 1e-300)
    scale = np.maximum(scale, SIGNAL_FLOOR * float(scale.max()))
    lin_t = APRIORI_FACTOR * (np.abs(read["tension"]) / scale).max(axis=(1, 2))
    mod_t = (np.abs(read["modulation"] - read["linear"]) / scale).max(axis=(1, 2)) + lin_t
    p_bar = frames.mean_pressure
    ratio = p_bar / p_star if p_star > 0 else float("inf")
    errors = {"linear": float(lin_t.max())} if frames.layered else {"linear": float(lin_t.max()),
                                                                    "modulation": float(mod_t.max())}
    out = errors, {"p_bar": p_bar, "p_star": p_star, "ratio": ratio}
    return (*out, lin_t if frames.layered else lin_t + mod_t) if per_frame else out


def cell_errors(frames: SceneFrames) -> dict | None:
    """The contact room's estimate (:func:`tactilab.forward.interface_model_errors`) on one periodic
    cell of the scene's texture, at the pressures that matter (a cell's mean pressure; a finger's mean
    and peak Hertz pressures, the larger estimate), strain at the sensors' depth; None for a texture
    without a period (a defect, a height map, a random square wave)."""
    rec = frames.scene.surface
    if frames.layered:  # its formulas are the half-space's
        return None
    if frames.periodic:
        cell, spacing = frames.heights(0) + frames.ridges(), frames.spacing
        pressures = [frames.mean_pressure]
    elif rec.kind == "sinusoidal_grating" or (rec.kind == "square_wave_grating" and rec.pattern == "regular"):
        period = float(rec.period_m)
        cell, spacing = rec.height_at(np.arange(CELL_NODES) * period / CELL_NODES), (period / CELL_NODES,)
        pressures = [frames.mean_pressure, frames.finger.contact.peak_pressure]
    elif rec.kind == "random_rough":
        cell, spacing = np.asarray(rec.heights_m), (float(rec.spacing_m),) * 2
        pressures = [frames.mean_pressure, frames.finger.contact.peak_pressure]
    else:
        return None
    if any(n % 2 for n in cell.shape) or min(cell.shape) < 4:
        return None
    m = frames.scene.material
    sp = spacing[0] if len(spacing) == 1 else spacing
    found = [interface_model_errors(cell, sp, p, m.young_modulus_pa, m.poisson_ratio, frames.scene.sensors.depth_m,
                                    components=frames.scene.sensors.components) for p in pressures]
    return {name: max(f[name] for f in found) for name in ("linear", "modulation")}


def _read(readout, rows) -> np.ndarray:
    qy = None if rows[0][2] is None else np.stack([r[2] for r in rows])
    stack = readout.stack(np.stack([r[0] for r in rows]), np.stack([r[1] for r in rows]), qy)
    return readout.split(readout.apply(stack))[0]


@dataclass
class ModelChoice:
    """What ``"auto"`` decided, and why.

    Attributes
    ----------
    model : str
        The chosen model.
    reason : str
        One sentence: the pressure ratio, the estimates against tol, the confirming frames.
    tol : float
    apriori, aposteriori, errors : dict
        Per cheap model: the a-priori estimate, the error measured on the frames solved exactly, and
        the estimate reported (the larger of the a-priori one and twice the measured one: the factor
        stands for the frames not solved).
    pressures : dict
        See :func:`apriori_errors`.
    check_frames : list of int
    """

    model: str
    reason: str
    tol: float
    apriori: dict
    aposteriori: dict
    errors: dict
    pressures: dict
    check_frames: list = field(default_factory=list)


def choose_model(frames: SceneFrames, tol: float, *, n_check: int = CHECK_FRAMES) -> ModelChoice:
    """Pick the cheapest model whose estimated error is within ``tol`` (a-priori on 16 frames spread over
    the scan, then confirmed on the ``n_check`` of them with the largest estimates, solved exactly, cold)."""
    n = frames.n_frames
    sample = np.unique(np.linspace(0, n - 1, min(n, APRIORI_FRAMES)).round().astype(int))
    apriori, pressures, per_frame = apriori_errors(frames, sample, per_frame=True)
    cell = cell_errors(frames)
    if cell is not None:  # the contact room's periodic-cell estimate, where the texture has a period
        apriori = {m: max(apriori[m], cell[m]) for m in apriori}
    check = np.sort(sample[np.argsort(per_frame, kind="stable")[::-1][:n_check]])  # where the estimates are largest
    exact = run_model(frames, "exact", check, warm_start=False)
    post = {m: signal_error(run_model(frames, m, check).values, exact.values) for m in frames.cheap_models}
    errors = {m: max(apriori[m], POSTERIORI_FACTOR * post[m]) for m in post}
    chosen = next(m for m in CHEAP_FIRST if m == "exact" or (m in errors and errors[m] <= tol))
    state = (f"mean pressure {'above' if pressures['ratio'] >= 1 else 'below'} the texture's full-contact "
             f"pressure p* = {pressures['p_star'] * 1e-3:.3g} kPa")
    verdict = {m: ("within" if errors[m] <= tol else "above") for m in errors}
    if frames.layered:  # the linear model only (modulation is a half-space formula)
        reason = (f"p_bar/p* = {pressures['ratio']:.3g} ({state}); layered skin: estimated error of linear "
                  f"{errors['linear']:.2g} ({verdict['linear']} tol {tol:g}); a priori {apriori['linear']:.2g}, "
                  f"measured on frames {', '.join(str(int(i)) for i in check)} solved exactly {post['linear']:.2g}")
        return ModelChoice(chosen, reason, float(tol), apriori, post, errors, pressures, [int(i) for i in check])
    reason = (f"p_bar/p* = {pressures['ratio']:.3g} ({state}); estimated error of modulation {errors['modulation']:.2g} "
              f"({verdict['modulation']} tol {tol:g}), linear {errors['linear']:.2g} ({verdict['linear']}); a priori "
              f"{apriori['modulation']:.2g} / {apriori['linear']:.2g}, measured on frames "
              f"{', '.join(str(int(i)) for i in check)} solved exactly {post['modulation']:.2g} / {post['linear']:.2g}"
              + ("" if cell is None else f"; the periodic-cell estimate (interface_model_errors) "
                 f"{cell['modulation']:.2g} / {cell['linear']:.2g} is in the a-priori one"))
    return ModelChoice(chosen, reason, float(tol), apriori, post, errors, pressures, [int(i) for i in check])


def scene_signals(scene, model: str | None = None, *, grid_spacing: float | None = None,
                  progress: bool = False) -> tuple[np.ndarray, dict]:
    """A scene's sensor signals under its interface model (``scene.contact.model`` unless ``model``).

    Returns
    -------
    values : ndarray, shape (n_frames, n_sensors, n_components)
        Pa (stress) or tensor strain.
    info : dict
        ``"model"``, ``"reason"``, ``"tol"``, ``"errors"`` (per cheaper model: its estimated or
        measured error for this scene), ``"error_basis"`` (how they were obtained), ``"pressures"``,
        ``"seconds"`` (the model's run), ``"total_seconds"`` (with the choice and the error estimates),
        ``"iterations"`` (exact: median per frame), ``"frames"`` (the SceneFrames).
    """
    model = scene.contact.model if model is None else model
    if model not in ("auto", "exact", "linear", "modulation"):
        raise ValueError(f"model: must be one of 'auto', 'exact', 'linear', 'modulation', got {model!r}")
    if scene.contact.fingerprint_period_m is not None and scene.contact.fingerprint_height_m is None \
            and model != "modulation":
        raise ValueError(f"contact.fingerprint_height: the {model!r} model puts the ridges in the gap and needs their "
                         "height; give fingerprint_height (e.g. \"20um\") or model = \"modulation\"")
    if scene.material.is_layered:
        refuse_layered_modulation(model)
    frames = SceneFrames.from_scene(scene, grid_spacing)
    tol = float(scene.contact.tol)
    t0 = time.perf_counter()
    if model == "auto":
        choice = choose_model(frames, tol)
        run = run_model(frames, choice.model, progress=progress)
        info = dict(model=choice.model, reason=f"auto: {choice.reason}", errors=dict(choice.errors),
                    error_basis="a priori and on frames solved exactly", pressures=choice.pressures)
        if choice.model == "exact":  # the cheap models cost little: measure their errors on the whole scan
            info["errors"] = {m: signal_error(run_model(frames, m).values, run.values) for m in frames.cheap_models}
            info["error_basis"] = "measured on every frame against the exact model"
    else:
        run = run_model(frames, model, progress=progress)
        info = dict(model=model, reason="the scene's [contact] model", errors={}, error_basis="not estimated",
                    pressures={})
        if model == "exact":  # the cheap models cost little: their errors on the whole scan, for the record
            info.update(errors={m: signal_error(run_model(frames, m).values, run.values)
                                for m in frames.cheap_models},
                        error_basis="measured on every frame against the exact model")
        else:
            sample = np.unique(np.linspace(0, frames.n_frames - 1, min(frames.n_frames, APRIORI_FRAMES)).round())
            apriori, pressures = apriori_errors(frames, sample.astype(int))
            cell = cell_errors(frames)
            if cell is not None:
                apriori = {m: max(apriori[m], cell[m]) for m in apriori}
            info.update(errors={model: apriori[model]}, error_basis="a priori (no frame solved exactly)",
                        pressures=pressures)
    info.update(tol=tol, seconds=run.seconds, total_seconds=time.perf_counter() - t0, frames=frames,
                iterations=None if run.iterations is None else float(np.median(run.iterations)))
    return run.values, info
