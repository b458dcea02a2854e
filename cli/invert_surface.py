"""``tactilab invert RECORDING --scene SCENE --target surface``: the surface the finger touched.

Parse, call :func:`tactilab.inversion.invert_surface`, print: writes ``surface.nc`` and
``surface.png`` and prints the resolved band, the touched fraction and the context posterior.
"""

from __future__ import annotations

import argparse
from pathlib import Path

#: the default prior's correlation length and Hurst exponent (a self-affine profile)
PRIOR_LENGTH = "0.2mm"
PRIOR_HURST = 0.8
#: the default prior rms height when the scene's surface states none
PRIOR_RMS = "5um"


def add_surface_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--target", choices=("defect", "surface"), default="defect",
                        help="defect (default): the defect's position and load profile; surface: the surface "
                             "heights the finger touched, through the solved contact (surface.nc, surface.png)")
    parser.add_argument("--geometry", choices=("line", "patch"), default="line",
                        help="--target surface: a profile h(x) with ridges along y (line, default) or h(x, y) "
                             "under the finger (patch)")
    parser.add_argument("--prior-rms", default=None,
                        help="--target surface: the prior's rms height (a length, e.g. 5um; default: the scene "
                             f"surface's rms when it states one, else {PRIOR_RMS})")
    parser.add_argument("--prior-length", default=PRIOR_LENGTH,
                        help=f"--target surface: the prior's correlation length (a length; default {PRIOR_LENGTH}); "
                             f"the prior is self-affine with Hurst exponent {PRIOR_HURST}")


def _scene_rms(scene) -> float | None:
    """The rms height the scene's surface record states (a sinusoid's A / sqrt 2), or None."""
    rec = scene.surface
    for name in ("rms_height_m",):
        if getattr(rec, name, None):
            return float(getattr(rec, name))
    if rec.kind == "sinusoidal_grating":
        return float(rec.amplitude_m) / 2**0.5
    return None


def context_priors(names, scene) -> dict:
    """``--sample`` names -> priors around the scene's values: normal force and modulus log-normal
    (x/1.35), friction normal (sd 0.1, or uniform on [0, 1] for a frictionless scene)."""
    from math import log

    from tactilab.inversion import LogNormal, Normal, Uniform

    out = {}
    for name in names:
        if name == "normal_force":
            if scene.contact.normal_force_n is None:
                raise ValueError("--sample: normal_force is not a parameter of this scene (a periodic cell is "
                                 "loaded by its mean pressure); drop it")
            out[name] = LogNormal(float(scene.contact.normal_force_n), log(1.35))
        elif name == "young_modulus":
            out[name] = LogNormal(float(scene.material.young_modulus_pa), log(1.35))
        elif name == "friction":
            mu = float(scene.contact.friction_coefficient)
            out[name] = Normal(mu, 0.1) if mu > 0 else Uniform(0.0, 1.0)
        else:
            raise ValueError(f"--sample: {name!r} is not a context parameter of the surface inversion; use "
                             "normal_force, friction, young_modulus")
    return out


def _warn_model(recording, path: Path) -> None:
    """One warning line when the recording was made with another interface model than the exact one."""
    import warnings

    from tactilab.data_schemas.interface_model import model_mismatch, recording_model

    line = model_mismatch(recording_model(recording, path), "exact", "the surface inversion")
    if line is not None:
        warnings.warn(line, UserWarning, stacklevel=3)


def surface_lengths(args) -> tuple[float | None, float]:
    """``--prior-rms`` (None: from the scene) and ``--prior-length`` in m, checked before any file is read."""
    from tactilab.core import rules
    from tactilab.data_schemas.units import to_si

    out = []
    for flag, text in (("--prior-rms", args.prior_rms), ("--prior-length", args.prior_length)):
        value = None if text is None else to_si(text, "length", name=flag)
        out.append(None if value is None else rules.positive(value, flag, "m", fix="give a length, e.g. 5um"))
    return out[0], out[1]


def run_surface(args, scene, recording, report, out: Path, lengths) -> int:
    import numpy as np

    from tactilab.data_schemas.units import to_si
    from tactilab.inversion import StationaryPrior, invert_surface

    rms, length = lengths
    rms = rms if rms is not None else (_scene_rms(scene) or to_si(PRIOR_RMS, "length"))
    prior = StationaryPrior(variance=rms**2, correlation_length=length, kind="self_affine", hurst=PRIOR_HURST)
    names = tuple(q.strip() for q in args.sample.split(",") if q.strip())
    with report.collecting_warnings():
        _warn_model(recording, Path(args.recording))
        post = invert_surface(scene, recording, geometry=args.geometry, prior=prior,
                              context=context_priors(names, scene), rng=np.random.default_rng(args.seed))
        post.to_netcdf(out / "surface.nc")
        post.plot(out / "surface.png")
    band = post.resolvable_band
    report.computed.append(f"surface: {post.geometry} of {post.touched.size} nodes at {post.spacing * 1e6:.3g} um; "
                           f"touched fraction {post.touched_fraction:.3f}; resolved wavelengths >= "
                           f"{band['wavelength_min'] * 1e3:.3g} mm (|k| <= {band['k_max'] * 1e-3:.3g} rad/mm)")
    for name, c in post.context.items():
        report.computed.append(f"context posterior: {name} = {c['mean']:.4g} +- {c['sd']:.2g} {c['units']} "
                               f"(90 %: {c['q05']:.4g} .. {c['q95']:.4g})")
    report.method = (f"surface: Gauss-Newton MAP through the solved contact, Laplace posterior (context "
                     f"{', '.join(names) or 'fixed'} marginalised); prior self-affine, rms {rms * 1e6:.3g} um, "
                     f"correlation length {length * 1e3:.3g} mm")
    touched_sd = post.std[post.touched]
    report.error_estimate = (f"surface: posterior sd (touched nodes) median {np.median(touched_sd) * 1e6:.3g} um; "
                             + post.message)
    report.data.update(touched_fraction=post.touched_fraction, resolvable_band=band,
                       context={k: {q: v for q, v in c.items() if q != 'units'} for k, c in post.context.items()})
    report.emit(args.json)
    return 0
