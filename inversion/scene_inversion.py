"""Invert a Recording of a defect scene: the defect's position by emcee, and the load profile
along the scan line by the exact linear-Gaussian posterior.

Data preparation (:func:`defect_problem`): the recording must match the scene's sensors (ids,
components; quantity "stress" in Pa or "strain", tensor strain) and scan (number of samples); the contact's own stress is constant
in the finger frame, so it is removed by subtracting each channel's median over time (the
defect passes in a small share of the scan); the sensors with the largest signal are kept and
the time axis is decimated to keep at most ``max_data`` values.

Profile (:func:`defect_profile`): the baseline-free signal is linear in an irregularity load
density ``s(x)`` (m^2 of effective defect area per m of scan line, at y = 0): column j of the
operator is :class:`DefectScanModel` with the defect at ``x_j``. Its regularisation strength is
chosen by the four criteria, and the credible band comes from the equivalent Gaussian prior.
"""

from __future__ import annotations

import numpy as np

from tactilab.data_schemas.recording import Recording

from .criteria import CriteriaResult
from .gaussian import GaussianPosterior, gaussian_posterior
from .linear import invert_linear
from .mcmc import MCMCResult, sample_scene_posterior
from .scene_params import DefectScanModel, LogNormal, Normal, Uniform, defect_footprint

__all__ = ["defect_problem", "invert_defect_position", "defect_profile"]


def defect_problem(scene, recording: Recording, max_data: int = 1500, max_sensors: int = 6, *,
                   footprint: bool = True):
    """Check scene and recording against each other and build the defect model and data.

    ``footprint``: model the defect with the size and shape the scene records (its pressure
    averaged over :func:`~tactilab.inversion.scene_params.defect_footprint`; an edge step stays a
    point), or as a point (False).

    Returns
    -------
    model : DefectScanModel
    data : ndarray, shape (model.n_data,), Pa or strain as recorded (baseline removed)
    info : dict
        ``sensor_ids`` kept, ``time_stride``, ``noise_std`` (Pa or strain), ``quantity``, ``truth`` (the scene's defect
        position, for reports), ``contact_radius`` (m).
    """
    if scene.contact is None:
        raise ValueError("scene.contact: the defect inversion needs a finger contact (Hertz); this scene has none")
    if getattr(scene.surface, "kind", None) != "defect":
        raise ValueError(f"scene.surface: the defect inversion needs an isolated defect surface, got kind "
                         f"{getattr(scene.surface, 'kind', None)!r}")
    recording.check_matches(scene.sensors)
    if recording.quantity not in ("stress", "strain"):
        raise ValueError(f"recording.quantity: the defect model predicts stress (Pa) or tensor strain, got "
                         f"{recording.quantity!r}; record stress or strain sensors")
    n = scene.scan.n_samples
    if recording.n_times != n:
        raise ValueError(f"recording: {recording.n_times} samples, but the scene's scan has {n} "
                         "(duration x sampling rate); pair the recording with the scene that produced it")
    values = np.asarray(recording.values, dtype=float)
    bad = ~np.isfinite(values)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"recording.values: must be finite, found {values[idx]} at (time, sensor, component) "
                         f"{idx}; drop or interpolate bad samples")
    noise = float(scene.sensors.noise_std)
    if noise <= 0:
        raise ValueError(f"scene.sensors.noise_std: the likelihood needs the noise level ({recording.unit}) > 0, "
                         "got 0; set noise_std in the scene's [sensors] table")
    signal = values - np.median(values, axis=0, keepdims=True)
    energy = np.sqrt(np.mean(signal**2, axis=(0, 2)))
    keep = np.sort(np.argsort(energy)[::-1][:max_sensors])
    per_time = keep.size * recording.n_components
    stride = max(1, int(np.ceil(n * per_time / max_data)))
    u = scene.scan.positions_m[::stride]
    c = scene.contact
    E, nu = scene.material.half_space_constants("the defect inversion")
    model = DefectScanModel(u, scene.sensors.positions_m[keep], recording.components,
                            finger_radius=c.finger_radius_m, poisson_ratio=nu,
                            quantity=recording.quantity,
                            footprint=defect_footprint(scene.surface) if footprint else None)
    from tactilab.forward.contact import HertzContact

    hertz = HertzContact(normal_force=c.normal_force_n, finger_radius=c.finger_radius_m,
                         young_modulus=E, poisson_ratio=nu)
    info = {"sensor_ids": [recording.sensor_ids[i] for i in keep], "time_stride": stride, "noise_std": noise,
            "quantity": recording.quantity,
            "truth": tuple(scene.surface.position_m), "contact_radius": hertz.contact_radius}
    return model, signal[::stride][:, keep, :].ravel(), info


def _prepared(problem, scene, recording, max_data, footprint):
    """The caller's prepared ``(model, data, info)``, or :func:`defect_problem` run now."""
    if problem is None:
        return defect_problem(scene, recording, max_data=max_data, footprint=footprint)
    try:
        model, data, info = problem
    except (TypeError, ValueError):
        raise ValueError(f"problem: expected the (model, data, info) that defect_problem returns, got "
                         f"{type(problem).__name__}; pass defect_problem(scene, recording) or None") from None
    if np.shape(data) != (model.n_data,):
        raise ValueError(f"problem: data holds {np.size(data)} values but the model predicts {model.n_data}; "
                         "pass the unchanged result of defect_problem(scene, recording)")
    return model, data, info


def _fixed(scene) -> dict:
    return dict(friction=float(scene.contact.friction_coefficient), depth=float(scene.sensors.depth_m),
                young_modulus=float(scene.material.young_modulus_pa), normal_force=float(scene.contact.normal_force_n))


def _amplitude_scale(model, data, fixed, x_grid) -> float:
    g = model.design(dict(fixed, x0=x_grid, y0=np.zeros_like(x_grid)))
    return 10.0 * float(np.max(np.abs(data))) / max(float(np.max(np.abs(g))), 1e-300)


EXTRA = ("friction", "depth", "young_modulus", "normal_force")


def invert_defect_position(scene, recording: Recording, rng: np.random.Generator, *, sample=(),
                           max_data: int = 1500, progress: bool = False, footprint: bool = True,
                           problem: tuple | None = None, **sampler_options) -> tuple[MCMCResult, dict]:
    """Posterior of the defect position (x0, y0) and optionally other scene parameters, by emcee.

    Priors: x0 uniform over the scanned range (contact centre path widened by the contact
    radius), y0 uniform over +-1 contact radius; parameters named in ``sample`` get a default
    prior around the scene's value (friction: uniform on [0, 1]; depth, young_modulus,
    normal_force: log-normal with median at the scene value and a factor-1.35 (sigma_log 0.3)
    spread); the rest stay fixed at the scene's values. The defect area ``S_d`` is integrated
    out under N(0, s^2) with s ten times the amplitude that explains the largest datum. With the
    area integrated out, young_modulus and normal_force act only through the contact radius, so
    sampling both leaves a ridge (F/E): the result reports it.

    The defect has the size and shape the scene records (``footprint=True``, default; see
    :func:`defect_problem`): a point model of the example 0.5 mm bump under a 3 mm deep sensor
    array puts x0 about 4 um off (one posterior sd; its 95 % intervals then cover the truth
    in 150 of 200 noise draws, docs/inversion.md); the finite model removes that bias.

    ``problem``: the ``(model, data, info)`` of :func:`defect_problem` when the caller has prepared
    it already (``tactilab invert`` prepares it once for the position and the profile); then
    ``max_data`` and ``footprint`` are those it was prepared with.
    """
    sample = tuple(sample)
    unknown = [q for q in sample if q not in EXTRA]
    if unknown:
        raise ValueError(f"sample: unknown parameter(s) {unknown}; choose from {', '.join(EXTRA)} "
                         "(x0 and y0 are always sampled)")
    model, data, info = _prepared(problem, scene, recording, max_data, footprint)
    a = info["contact_radius"]
    u = model.scan_positions
    fixed = _fixed(scene)
    priors = dict(fixed, x0=Uniform(float(u.min() - a), float(u.max() + a)), y0=Uniform(-a, a))
    for q in sample:
        priors[q] = Uniform(0.0, 1.0) if q == "friction" else LogNormal(fixed[q], 0.3)
    scale = _amplitude_scale(model, data, fixed, np.linspace(u.min(), u.max(), 64))
    result = sample_scene_posterior(model, data, info["noise_std"], priors, Normal(0.0, scale), rng=rng,
                                    progress=progress, **sampler_options)
    return result, info


def defect_profile(scene, recording: Recording, *, n_grid: int = 200, criterion: str = "evidence",
                   max_data: int = 1500, problem: tuple | None = None
                   ) -> tuple[GaussianPosterior, CriteriaResult, np.ndarray]:
    """Load-density profile s(x) along the scan line with its Gaussian credible band.

    ``problem``: the ``(model, data, info)`` of :func:`defect_problem` when already prepared (as in
    :func:`invert_defect_position`); else it is prepared here with ``max_data``.

    Returns
    -------
    posterior : GaussianPosterior
        Mean and pointwise std of s(x), m^2 per m (dense path).
    criteria : CriteriaResult
        The four criteria for the identity penalty; ``criterion`` picks lam.
    x : ndarray, shape (n_grid,)
        World x of the profile nodes, m.
    """
    model, data, info = _prepared(problem, scene, recording, max_data, True)
    u = model.scan_positions
    a = info["contact_radius"]
    x = np.linspace(u.min() - a, u.max() + a, int(n_grid))
    dx = float(x[1] - x[0])
    g = model.design(dict(_fixed(scene), x0=x, y0=np.zeros_like(x))).T * dx  # (n_data, n_grid)
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        lin = invert_linear(g, data, penalty="identity", criterion=criterion, noise_std=info["noise_std"], spacing=dx)
    for w in caught:  # surface the disagreement warning at the caller
        warnings.warn(str(w.message), UserWarning, stacklevel=2)
    prior = np.full(x.size, info["noise_std"] ** 2 / lin.lam)  # Tikhonov identity prior, white
    post = gaussian_posterior(g, data, prior, info["noise_std"], spacing=dx)
    return post, lin.criteria, x
