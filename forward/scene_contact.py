"""A scan through the solved contact: every frame's contact solved, warm-started from the previous one.

The finger (or the nominally flat skin of a periodic cell) stays on one grid in the finger frame;
the surface slides under it. Frame ``i`` has its own gap (the finger's curvature minus the
surface's heights under it, plus the fingerprint ridges), and :func:`solve_contact` solves it,
starting from frame ``i - 1``'s solution moved by the surface's step. Friction: full sliding
(``q = mu p`` along ``slide_direction``) or, per frame, partial slip with a tangential force
``slip_ratio * mu F`` (the onset of a scan, or a press with adhesion). Sensors read the solved
tractions through one weight matrix (:class:`.scene_readout.SensorReadout`), batched over frames.

Conventions (docs/theory.md section 1): tractions act on the skin, in Pa; heights and the gap in m;
the grid's node ``j`` at ``x_j = (j - nx // 2) dx``; forces in N (N/m in plane strain).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from tactilab.core import rules as check

from .contact import solve_contact
from .scene_readout import SensorReadout

#: nodes added around frame 0's contact for the readout's window (and a fraction of its width)
WINDOW_MARGIN_NODES = 8
WINDOW_MARGIN_FRACTION = 0.15


@dataclass(frozen=True)
class ScanSolution:
    """The solved contact of every frame of a scan.

    Attributes
    ----------
    pressure, qx, qy : ndarray, shape (n_frames, *grid) or None
        Tractions on the skin per frame, Pa (None when not kept; ``qy`` None in plane strain).
    contact : ndarray of bool, shape (n_frames, *grid) or None
        Contact nodes per frame (None when tractions are not kept).
    iterations : ndarray of int, shape (n_frames,)
        The contact solver's iterations on the full grid per frame.
    contact_fraction, normal_force, error_estimate : ndarray, shape (n_frames,)
        Contact nodes over all nodes; total normal force (N; N/m in plane strain); the solver's
        bound on max |pressure error| / peak pressure.
    converged : ndarray of bool, shape (n_frames,)
    outputs : list of ndarray or None
        Per sensor array, shape (n_frames, n_sensors, n_components): Pa (stress) or tensor strain.
    warm_start : bool
        Whether frames were warm-started (from the previous frame, or from ``initial``).
    seconds : dict
        Wall time of ``"contact"`` (the solves) and ``"readout"`` (weights and products), s.
    """

    pressure: np.ndarray | None
    qx: np.ndarray | None
    qy: np.ndarray | None
    contact: np.ndarray | None
    iterations: np.ndarray
    contact_fraction: np.ndarray
    normal_force: np.ndarray
    error_estimate: np.ndarray
    converged: np.ndarray
    outputs: list | None
    warm_start: bool
    seconds: dict

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.iterations.size)


def finger_gap(shape, spacing, finger_radius: float) -> np.ndarray:
    """The fingertip's curvature ``r^2 / (2 R)`` on a grid centred on the contact (m).

    Parameters
    ----------
    shape : (nx,) or (ny, nx)
    spacing : float or (dx, dy)
        m, x first.
    finger_radius : float
        R in m (> 0).

    Returns
    -------
    ndarray, shape ``shape``, m
    """
    if not math.isfinite(finger_radius) or finger_radius <= 0:
        raise ValueError(f"finger_radius: must be finite and > 0 m, got {finger_radius!r}; a fingertip is ~0.01 m")
    h = check.spacing(spacing, len(shape))
    x = (np.arange(shape[-1]) - shape[-1] // 2) * h[0]
    if len(shape) == 1:
        return x * x / (2 * finger_radius)
    y = (np.arange(shape[0]) - shape[0] // 2) * h[1]
    return (x[None, :] ** 2 + y[:, None] ** 2) / (2 * finger_radius)


def ridge_heights(x, period: float, height: float, offset: float = 0.0) -> np.ndarray:
    """Fingerprint ridges as heights of the skin towards the surface (m): ``height`` on the ridges
    (the first half of each period from ``offset``, as :class:`~.finger.Fingerprint`), 0 in the grooves."""
    phase = np.mod(np.asarray(x, dtype=float) - offset, period) / period
    return np.where(phase < 0.5, float(height), 0.0)


def _frames(gaps, n_frames):
    if callable(gaps):
        if n_frames is None or int(n_frames) < 1:
            raise ValueError(f"n_frames: a callable gap needs the number of frames (>= 1), got {n_frames!r}")
        return gaps, int(n_frames)
    arr = np.asarray(gaps, dtype=float)
    if arr.ndim not in (2, 3) or arr.shape[0] < 1:
        raise ValueError(f"gaps: expected an array of shape (n_frames, nx) or (n_frames, ny, nx) in m, or a "
                         f"callable gap(i), got shape {arr.shape}")
    if n_frames is not None and int(n_frames) != arr.shape[0]:
        raise ValueError(f"n_frames: {n_frames!r} differs from the {arr.shape[0]} frames of gaps; omit it")
    return (lambda i: arr[i]), arr.shape[0]


def _per_frame(value, n: int, name: str, rule: str) -> np.ndarray:
    arr = np.broadcast_to(np.asarray(value, dtype=float), (n,)) if np.ndim(value) == 0 else np.asarray(value, float)
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: expected a finite number or {n} finite values (one per frame), {rule}, got "
                         f"shape {np.shape(value)}")
    return arr


def _moved(sol, shift: int):
    """``sol`` moved by ``shift`` nodes along x (the surface's step between frames), for a warm start."""
    if shift == 0:
        return sol
    coarse = sol._coarse_pressure
    if coarse is not None:  # the check grid takes every other node: move it only by whole coarse nodes
        coarse = np.roll(coarse, shift // 2, axis=-1) if shift % 2 == 0 else coarse
    return replace(sol, pressure=np.roll(sol.pressure, shift, axis=-1), _coarse_pressure=coarse)


def _window(contact: np.ndarray) -> tuple[slice, ...]:
    """Frame 0's contact bounding box, widened by a margin, as slices of the grid."""
    out = []
    for axis, n in enumerate(contact.shape):
        other = tuple(a for a in range(contact.ndim) if a != axis)
        hit = np.flatnonzero(contact.any(axis=other) if other else contact)
        if hit.size == 0:
            return tuple(slice(0, m) for m in contact.shape)
        lo, hi = int(hit[0]), int(hit[-1]) + 1
        pad = WINDOW_MARGIN_NODES + int(WINDOW_MARGIN_FRACTION * (hi - lo))
        out.append(slice(max(0, lo - pad), min(n, hi + pad)))
    return tuple(out)


def solve_scan(skin, gaps, spacing, *, n_frames: int | None = None, normal_force=None, mean_pressure=None,
               periodic: bool = False, friction: float = 0.0, slide_direction=(1.0, 0.0), slip_ratio=None,
               shifts=None, warm_start: bool = True, initial=None, estimate_error: bool = True, sensors=None,
               keep_tractions: bool = True, tol: float = 1e-8, batch: int = 64, progress: bool = False) -> ScanSolution:
    """Solve the contact of every frame of a scan and read the sensors from the solved tractions.

    Parameters
    ----------
    skin : HalfSpace
        E in Pa, nu.
    gaps : ndarray, shape (n_frames, nx) or (n_frames, ny, nx), or callable
        Each frame's gap in m (``solve_contact``'s ``gap``: the finger's curvature minus the surface
        heights under it, see :func:`finger_gap`), or ``gap(i) -> ndarray`` with ``n_frames``.
    spacing : float or (dx, dy)
        Grid spacing in m, x first.
    n_frames : int, optional
        The number of frames, for a callable ``gaps``.
    normal_force, mean_pressure : float or array of shape (n_frames,)
        Exactly one: the finger's force on the skin (N; N/m in plane strain) or a periodic cell's
        mean pressure (Pa), per frame or for all.
    periodic : bool
        True: each frame's grid is one period (give ``mean_pressure``).
    friction : float
        Coulomb coefficient mu >= 0. Frames slide fully (``q = mu p`` along ``slide_direction``)
        unless ``slip_ratio`` says otherwise; mu = 0 is frictionless.
    slide_direction : (float, float)
        Direction of the tangential traction ON THE SKIN, x first (``(-1, 0)`` for a finger sliding
        towards +x over a fixed surface).
    slip_ratio : float or array of shape (n_frames,), optional
        Q / (mu F) in [0, 1] per frame: below 1 the frame is a partial-slip solve with the tangential
        force ``slip_ratio * mu F`` along ``slide_direction`` (Cattaneo-Mindlin's loading: the normal
        load first, then Q); 1 (or None) is full sliding.
    shifts : int or array of int, shape (n_frames,), optional
        Nodes the surface moved along +x in the finger frame since the previous frame (a finger
        moving one node towards +x: -1); the warm start moves the previous solution by as much.
        Default 0 (the previous solution as it is).
    warm_start : bool
        Start each frame from the previous one (the cold solve's answer to ``tol``, tested).
    initial : ndarray, shape (n_frames, *grid), optional
        Pressures (Pa) to start each frame from instead of the previous frame: an earlier scan's
        solution at nearby gaps (an iteration's previous iterate); the answer is the same to ``tol``.
    estimate_error : bool
        False: skip each warm-started frame's check solve on the grid of twice the spacing, which
        costs about as much as the frame's own solve; their ``error_estimate`` is then NaN (not
        estimated). A cold frame (the first, without ``initial``) still runs it: it is its start.
    sensors : SensorArray, sequence of SensorArray or SensorReadout, optional
        Sensors (finger frame) read through one weight matrix over a window of the grid around frame
        0's contact (or the given readout's window); a frame whose contact leaves the window rebuilds
        it over the whole grid.
    keep_tractions : bool
        Keep every frame's tractions and contact mask (n_frames x grid values each).
    tol : float
        The contact solver's relative gap residual (``solve_contact``'s ``tol``).
    batch : int
        Frames per readout product.
    progress : bool
        A tqdm bar over frames.

    Returns
    -------
    ScanSolution

    Raises
    ------
    ValueError
        On bad input (and everything ``solve_contact`` refuses), in one line naming the argument.
    """
    gap_of, n = _frames(gaps, n_frames)
    if (normal_force is None) == (mean_pressure is None):
        raise ValueError("normal_force, mean_pressure: give exactly one (N for a finger, Pa for a periodic cell), "
                         f"got normal_force={normal_force!r}, mean_pressure={mean_pressure!r}")
    load_name = "normal_force" if normal_force is not None else "mean_pressure"
    loads = _per_frame(normal_force if normal_force is not None else mean_pressure, n, load_name, "each > 0")
    ratio = None if slip_ratio is None else _per_frame(slip_ratio, n, "slip_ratio", "each in [0, 1]")
    if ratio is not None and (np.any(ratio < 0) or np.any(ratio > 1)):
        raise ValueError(f"slip_ratio: Q / (mu F) must lie in [0, 1] (1 = full sliding), got values in "
                         f"[{ratio.min():g}, {ratio.max():g}]")
    if ratio is not None and np.any(ratio < 1) and not friction > 0:
        raise ValueError(f"slip_ratio: partial slip needs friction > 0, got friction={friction!r}; give mu or drop "
                         "slip_ratio")
    steps = np.zeros(n, dtype=np.int64) if shifts is None else np.broadcast_to(np.asarray(shifts), (n,))
    if not np.issubdtype(np.asarray(steps).dtype, np.integer):
        raise ValueError(f"shifts: whole nodes per frame (integers), got dtype {np.asarray(shifts).dtype}; round the "
                         "step or give None")
    if int(batch) < 1:
        raise ValueError(f"batch: frames per readout product must be >= 1, got {batch!r}")
    direction = np.asarray(slide_direction, dtype=float).ravel()
    if direction.size not in (1, 2) or not np.all(np.isfinite(direction)) or not np.any(direction):
        raise ValueError(f"slide_direction: expected a finite non-zero (dx, dy), got {slide_direction!r}; e.g. (1, 0)")
    direction = direction / np.linalg.norm(direction)
    first = np.asarray(gap_of(0), dtype=float)
    shape = first.shape
    starts = None if initial is None else np.asarray(initial, dtype=float)
    if starts is not None and (starts.shape != (n, *shape) or not np.all(np.isfinite(starts)) or np.any(starts < 0)):
        raise ValueError(f"initial: expected finite pressures >= 0 (Pa) of shape (n_frames, *grid) = {(n, *shape)}, "
                         f"got shape {starts.shape}; e.g. an earlier scan's pressure")
    spacing = check.spacing(spacing, len(shape))
    cell = math.prod(spacing)
    store = {k: (np.zeros((n, *shape)) if keep_tractions else None) for k in ("pressure", "qx")}
    store["qy"] = np.zeros((n, *shape)) if keep_tractions and len(shape) == 2 else None
    contact = np.zeros((n, *shape), dtype=bool) if keep_tractions else None
    stats = {k: np.zeros(n) for k in ("iterations", "contact_fraction", "normal_force", "error_estimate")}
    converged = np.zeros(n, dtype=bool)
    readout = sensors if isinstance(sensors, SensorReadout) else None
    if readout is not None and readout.sliding is not None:  # a folded readout reads q = mu p and nothing else
        mu, (fx, fy) = readout.sliding
        partial = ratio is not None and bool(np.any(ratio < 1))
        if partial or not np.isclose(mu, friction) or not np.allclose((fx, fy), (direction[0], direction[-1] * (
                direction.size > 1))):
            raise ValueError(f"sensors: the readout folds q = {mu:g} p along ({fx:g}, {fy:g}) into its weights, but the "
                             f"scan has friction {friction!r} along {tuple(direction)}"
                             + (" and partial-slip frames" if partial else "")
                             + "; build the SensorReadout without sliding=, or with the scan's friction and direction")
    outputs, pending = (None if readout is None else np.zeros((n, readout.n_outputs))), []
    seconds = {"contact": 0.0, "readout": 0.0}
    frames = range(n)
    if progress:
        from tqdm import tqdm

        frames = tqdm(frames, desc="contact frames", unit="frame")
    prev = None

    def flush():
        if pending:
            t = time.perf_counter()
            rows = np.stack([r for _, r in pending])
            values = readout.apply(rows)
            for k, (i, _) in enumerate(pending):
                outputs[i] = values[k]
            pending.clear()
            seconds["readout"] += time.perf_counter() - t

    for i in frames:
        g = first if i == 0 else np.asarray(gap_of(i), dtype=float)
        if g.shape != shape:
            raise ValueError(f"gaps: frame {i} has shape {g.shape}, frame 0 {shape}; every frame shares one grid")
        kw = {load_name: float(loads[i])}
        if friction > 0 and ratio is not None and ratio[i] < 1:
            total = float(loads[i]) if normal_force is not None else float(loads[i]) * cell * g.size
            q = float(ratio[i]) * friction * total
            kw.update(condition="partial", tangential_force=q * direction[0] if len(shape) == 1
                      else (q * direction[0], q * direction[1]))
        elif friction > 0:
            kw.update(condition="sliding", slide_direction=tuple(direction))
        if starts is not None:
            start = starts[i]
        else:
            start = _moved(prev, int(steps[i])) if (warm_start and prev is not None) else None
        t0 = time.perf_counter()
        sol = solve_contact(skin, g, spacing, periodic=periodic, friction=friction, tol=tol, initial=start,
                            estimate_error=estimate_error, **kw)
        seconds["contact"] += time.perf_counter() - t0
        prev = sol
        stats["iterations"][i], stats["contact_fraction"][i] = sol.iterations, sol.contact_fraction
        stats["normal_force"][i], stats["error_estimate"][i] = sol.normal_force, sol.error_estimate
        converged[i] = sol.converged
        if keep_tractions:
            store["pressure"][i], store["qx"][i], contact[i] = sol.pressure, sol.qx, sol.contact
            if store["qy"] is not None:
                store["qy"][i] = sol.qy
        if sensors is None:
            continue
        t = time.perf_counter()
        loads_read = ("p", "qx") if len(shape) == 1 else ("p", "qx", "qy")
        if readout is None or (not periodic and not _inside(sol.contact, readout.window)):
            flush()
            sliding = None if readout is None else readout.sliding
            if readout is None and (ratio is None or np.all(ratio >= 1)):  # every frame slides: fold q = mu p
                sliding = (float(friction), (float(direction[0]), float(direction[1]) if direction.size > 1 else 0.0))
            arrays = sensors if readout is None else readout.arrays
            window = None if (periodic or readout is not None) else _window(sol.contact)
            readout = SensorReadout(skin, shape, spacing, arrays, periodic=periodic, window=window, loads=loads_read,
                                    sliding=sliding)
            outputs = np.zeros((n, readout.n_outputs)) if outputs is None else outputs
        pending.append((i, readout.stack(sol.pressure[None], sol.qx[None],
                                         None if sol.qy is None else sol.qy[None])[0]))
        seconds["readout"] += time.perf_counter() - t
        if len(pending) >= int(batch):
            flush()
    if sensors is not None:
        flush()
    return ScanSolution(pressure=store["pressure"], qx=store["qx"], qy=store["qy"], contact=contact,
                        iterations=stats["iterations"].astype(int), contact_fraction=stats["contact_fraction"],
                        normal_force=stats["normal_force"], error_estimate=stats["error_estimate"],
                        converged=converged, outputs=None if readout is None else readout.split(outputs),
                        warm_start=bool(warm_start or starts is not None), seconds=seconds)


def _inside(contact: np.ndarray, window: Sequence[slice]) -> bool:
    return int(np.count_nonzero(contact)) == int(np.count_nonzero(contact[tuple(window)]))

