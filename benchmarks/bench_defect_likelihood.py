"""Time the defect likelihood, the inner loop of ``tactilab invert --method mcmc``.

Run: ``nice python benchmarks/bench_defect_likelihood.py [--calls 200] [--walkers 8] [--run]``

The scene of demo/inversion.py's defect section (``defect_demo_scene``: 3 x 3 sensors reading zz
and zx, a 0.5 mm bump modelled with its 96-point footprint), all 900 data values. Part 1 times
``DefectPosterior.log_marginal_likelihood`` on ``--walkers`` walkers per call, as emcee calls it
(half an ensemble per call), over ``--calls`` random positions: the minimum over 7 repeats of the
CPU time per call (process time, so that other work on a shared machine counts less). ``--run``
adds a whole seeded ``invert_defect_position`` (``max_data=500``, 1000 steps x 4 ensembles): its CPU
time, the number of likelihood calls and a SHA-1 of the draws (the same draws before and after a
change of the kernels show that the answers did not move).
"""

from __future__ import annotations

import argparse
import hashlib
import time

import numpy as np

from tactilab.data_schemas.recording import Recording
from tactilab.demo.inversion import defect_demo_scene
from tactilab.inversion import DefectScanModel, Normal, Uniform, defect_footprint, invert_defect_position
from tactilab.inversion.mcmc import DefectPosterior
from tactilab.inversion.scene_inversion import _fixed, defect_problem


def _recording(scene, rng):
    c = scene.contact
    model = DefectScanModel(scene.scan.positions_m, scene.sensors.positions_m, scene.sensors.components,
                            finger_radius=c.finger_radius_m, poisson_ratio=scene.material.poisson_ratio,
                            footprint=defect_footprint(scene.surface))
    truth = dict(x0=0.0, y0=0.0, friction=c.friction_coefficient, depth=scene.sensors.depth_m,
                 young_modulus=scene.material.young_modulus_pa, normal_force=c.normal_force_n)
    clean = model.simulate(truth, 5e-8)
    values = clean + rng.normal(0, scene.sensors.noise_std, clean.shape)
    return Recording.from_sensors(scene.sensors, values, scene.scan.sampling_rate_hz)


def per_call(scene, rec, walkers: int, calls: int, rng) -> float:
    """Minimum CPU seconds per likelihood call over 7 repeats."""
    model, data, info = defect_problem(scene, rec)
    a = info["contact_radius"]
    priors = dict(_fixed(scene), x0=Uniform(-5e-3, 5e-3), y0=Uniform(-a, a))
    post = DefectPosterior(model, data, info["noise_std"], priors, Normal(0.0, 1e-6))
    thetas = np.stack([rng.uniform(-2e-3, 2e-3, (calls, walkers)), rng.uniform(-a, a, (calls, walkers))], axis=-1)
    post.log_marginal_likelihood(thetas[0])
    best = np.inf
    for _ in range(7):
        t0 = time.process_time()
        for theta in thetas:
            post.log_marginal_likelihood(theta)
        best = min(best, (time.process_time() - t0) / calls)
    print(f"likelihood: {model.n_data} data, {walkers} walkers per call: {best * 1e3:.3f} ms CPU per call "
          f"(minimum of 7 repeats of {calls} calls)")
    return best


def whole_run(scene, rec) -> None:
    calls = [0]
    real = DefectPosterior.log_marginal_likelihood

    def counted(self, theta):
        calls[0] += 1
        return real(self, theta)

    DefectPosterior.log_marginal_likelihood = counted
    try:
        t0 = time.process_time()
        res, _ = invert_defect_position(scene, rec, np.random.default_rng(5), max_data=500, max_steps=1000,
                                        check_every=500)
        seconds = time.process_time() - t0
    finally:
        DefectPosterior.log_marginal_likelihood = real
    post = res.tree["posterior"]
    digest = hashlib.sha1(np.concatenate([post[v].values.ravel() for v in ("x0", "y0", "amplitude")]).tobytes())
    print(f"invert_defect_position: {seconds:.2f} s CPU, {calls[0]} likelihood calls, "
          f"{res.diagnostics['n_steps']} steps, draws sha1 {digest.hexdigest()[:12]}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=200, help="likelihood calls per repeat")
    parser.add_argument("--walkers", type=int, default=8, help="walkers per call")
    parser.add_argument("--run", action="store_true", help="also time a whole seeded invert_defect_position")
    args = parser.parse_args()
    scene = defect_demo_scene()
    rec = _recording(scene, np.random.default_rng(0))
    per_call(scene, rec, args.walkers, args.calls, np.random.default_rng(1))
    if args.run:
        whole_run(scene, rec)


if __name__ == "__main__":
    main()
