"""The exact scan engine (forward/scene_contact.py, forward/scene_readout.py): frames solved by the
contact engine, warm-started, read by one weight matrix.

Oracles: the readout against an independent field solve of the same tractions (HalfSpace.stress);
warm-started frames against cold solves; a scan that does not move against one static press."""

import numpy as np
import pytest

from tactilab.data_schemas import SensorArray
from tactilab.forward import HalfSpace, solve_contact
from tactilab.forward.scene_contact import finger_gap, ridge_heights, solve_scan
from tactilab.forward.scene_readout import SensorReadout

SKIN = HalfSpace(E=1e6, nu=0.5)
N, DX = 64, 50e-6


def _rough(rng, extra=8):
    return 1e-6 * rng.standard_normal((N, N + extra))


def _scan(rng, frames=4, **kw):
    g0 = finger_gap((N, N), DX, 10e-3)
    h = _rough(rng)
    gaps = np.stack([g0 - h[:, i:i + N] for i in range(frames)])
    return gaps, kw


def test_readout_equals_an_independent_field_solve(rng):
    gaps, _ = _scan(rng, frames=1)
    sens = SensorArray.grid(3, 3, 0.5e-3, 1e-3, components=("zz", "zx", "xx", "yz"))
    sc = solve_scan(SKIN, gaps, DX, normal_force=0.5, friction=0.5, slide_direction=(-1, 0), sensors=sens)
    sol = solve_contact(SKIN, gaps[0], DX, normal_force=0.5, friction=0.5, condition="sliding",
                        slide_direction=(-1, 0))
    field = SKIN.stress(sol.load(), [1e-3], points=sens.positions_m, components=("zz", "zx", "xx", "yz"))
    want = field.data["stress"].values.reshape(4, 9).T
    assert np.abs(sc.outputs[0][0] - want).max() <= 1e-10 * np.abs(want).max()


def test_warm_started_scan_equals_cold_solves_frame_by_frame(rng):
    gaps, _ = _scan(rng, frames=4)
    sens = SensorArray.grid(2, 2, 0.5e-3, 1e-3, quantity="strain", components=("zz", "zx"))
    kw = dict(normal_force=0.5, friction=0.5, slide_direction=(-1, 0), sensors=sens, tol=1e-10)
    warm = solve_scan(SKIN, gaps, DX, shifts=-1, **kw)
    cold = solve_scan(SKIN, gaps, DX, warm_start=False, **kw)
    for i in range(4):
        peak = cold.pressure[i].max()
        assert np.abs(warm.pressure[i] - cold.pressure[i]).max() <= 1e-6 * peak
        assert np.array_equal(warm.contact[i], cold.contact[i])
    scale = np.abs(cold.outputs[0]).max()
    assert np.abs(warm.outputs[0] - cold.outputs[0]).max() <= 1e-6 * scale
    assert warm.warm_start and not cold.warm_start


def test_a_scan_started_from_an_earlier_scan_without_check_solves_equals_a_cold_one(rng):
    """initial= (an earlier scan at nearby gaps) and estimate_error=False: the cold scan's pressures
    to the solver's tolerance, the skipped estimates NaN; a cold first frame still estimates."""
    gaps, _ = _scan(rng, frames=3)
    kw = dict(normal_force=0.5, friction=0.5, slide_direction=(-1, 0), tol=1e-10)
    cold = solve_scan(SKIN, gaps, DX, shifts=-1, **kw)
    nearby = solve_scan(SKIN, gaps + 2e-8 * rng.standard_normal(gaps.shape), DX, shifts=-1, **kw)
    fast = solve_scan(SKIN, gaps, DX, initial=nearby.pressure, estimate_error=False, **kw)
    skipped = solve_scan(SKIN, gaps, DX, shifts=-1, estimate_error=False, **kw)
    for got in (fast, skipped):
        assert np.abs(got.pressure - cold.pressure).max() <= 1e-6 * cold.pressure.max()
        assert np.array_equal(got.contact, cold.contact)
    assert np.isnan(fast.error_estimate).all() and fast.warm_start
    assert np.isfinite(skipped.error_estimate[0]) and np.isnan(skipped.error_estimate[1:]).all()
    with pytest.raises(ValueError, match=r"initial: expected finite pressures >= 0 \(Pa\) of shape"):
        solve_scan(SKIN, gaps, DX, initial=nearby.pressure[:2], **kw)


def test_a_scan_that_does_not_move_is_a_static_press(rng):
    gaps, _ = _scan(rng, frames=1)
    still = np.repeat(gaps, 3, axis=0)
    sc = solve_scan(SKIN, still, DX, normal_force=0.5, friction=0.5)
    sol = solve_contact(SKIN, gaps[0], DX, normal_force=0.5, friction=0.5, condition="sliding")
    for i in range(3):
        assert np.abs(sc.pressure[i] - sol.pressure).max() <= 1e-7 * sol.pressure.max()
    assert np.allclose(sc.normal_force, 0.5, rtol=1e-9)


def test_partial_slip_frames_carry_their_tangential_force(rng):
    gaps, _ = _scan(rng, frames=3)
    sc = solve_scan(SKIN, gaps, DX, normal_force=0.5, friction=0.5, slip_ratio=[0.0, 0.5, 1.0])
    q = sc.qx.sum(axis=(1, 2)) * DX * DX
    assert np.allclose(q, [0.0, 0.125, 0.25], atol=1e-6)


def test_the_readout_window_grows_when_the_contact_leaves_it(rng):
    g0 = finger_gap((N, N), DX, 10e-3)
    sens = SensorArray.grid(1, 1, 0.5e-3, 1e-3, components=("zz",))
    gaps = np.stack([g0, g0])
    forces = [0.01, 0.3]  # the second contact is far wider than the first one's window
    sc = solve_scan(SKIN, gaps, DX, normal_force=forces, sensors=sens)
    sol = solve_contact(SKIN, g0, DX, normal_force=0.3)
    want = SKIN.stress(sol.load(), [1e-3], points=sens.positions_m, components=("zz",)).data["stress"].values
    assert np.isclose(sc.outputs[0][1, 0, 0], want.ravel()[0], rtol=1e-10)


def test_plane_strain_periodic_scan_reads_the_periodic_field():
    n, L = 64, 1e-3
    x = (np.arange(n) - n // 2) * (L / n)
    gaps = np.stack([-1e-6 * np.cos(2 * np.pi * (x + s) / L) for s in (0.0, L / n)])
    sens = SensorArray(positions_m=[[0.0, 0.0], [0.2e-3, 0.0]], depth_m=0.3e-3, components=("zz", "xx"))
    sc = solve_scan(SKIN, gaps, L / n, mean_pressure=5e3, periodic=True, sensors=sens)
    sol = solve_contact(SKIN, gaps[1], L / n, mean_pressure=5e3, periodic=True)
    field = SKIN.stress(sol.load(), [0.3e-3], points=np.array([[0.0], [0.2e-3]]), components=("zz", "xx"))
    want = field.data["stress"].values.reshape(2, 2).T
    assert np.abs(sc.outputs[0][1] - want).max() <= 1e-9 * np.abs(want).max()


def test_ridges_are_raised_on_the_first_half_period():
    r = ridge_heights([0.0, 0.1e-3, 0.3e-3, 0.5e-3], 0.5e-3, 10e-6)
    assert np.allclose(r, [10e-6, 10e-6, 0.0, 10e-6])


@pytest.mark.parametrize("kw, match", [
    (dict(normal_force=0.5, mean_pressure=1e3), "give exactly one"),
    (dict(normal_force=0.5, slip_ratio=1.5, friction=0.5), "must lie in"),
    (dict(normal_force=0.5, slip_ratio=0.5), "needs friction > 0"),
    (dict(normal_force=[0.5, 0.5]), "one per frame"),
    (dict(normal_force=0.5, shifts=0.5), "whole nodes"),
    (dict(normal_force=0.5, batch=0), "batch"),
    (dict(normal_force=0.5, n_frames=3), "differs"),
])
def test_refusals(kw, match):
    gaps = finger_gap((N, N), DX, 10e-3)[None]
    with pytest.raises(ValueError, match=match):
        solve_scan(SKIN, gaps, DX, **kw)


def test_refusals_of_the_gap_and_the_readout():
    with pytest.raises(ValueError, match="n_frames"):
        solve_scan(SKIN, lambda i: np.zeros((N, N)), DX, normal_force=0.5)
    with pytest.raises(ValueError, match="gaps: expected"):
        solve_scan(SKIN, np.zeros(N), DX, normal_force=0.5)
    with pytest.raises(ValueError, match="finger_radius"):
        finger_gap((N, N), DX, -1.0)
    with pytest.raises(ValueError, match="sensors: expected"):
        SensorReadout(SKIN, (N, N), DX, [])
    sens = SensorArray.grid(1, 1, 0.5e-3, 1e-3, components=("zz",))
    ro = SensorReadout(SKIN, (N, N), DX, sens, window=(slice(10, 20), slice(10, 20)))
    with pytest.raises(ValueError, match="outside the readout's window"):
        ro.read(np.ones((1, N, N)))


def test_a_sliding_readout_folds_the_friction_into_the_weights(rng):
    sens = SensorArray.grid(2, 2, 0.5e-3, 1e-3, quantity="strain", components=("zz", "zx", "yy"))
    p = np.abs(rng.standard_normal((3, N, N)))
    full = SensorReadout(SKIN, (N, N), DX, sens, loads=("p", "qx", "qy"))
    folded = SensorReadout(SKIN, (N, N), DX, sens, loads=("p", "qx", "qy"), sliding=(0.4, (0.6, 0.8)))
    want = full.read(p, 0.4 * 0.6 * p, 0.4 * 0.8 * p)[0]
    assert np.allclose(folded.read(p)[0], want, rtol=0, atol=1e-12 * np.abs(want).max())
    sparse = p * (rng.random(p.shape) < 0.05)  # few loaded nodes: the sparse product
    assert np.allclose(folded.read(sparse)[0], full.read(sparse, 0.24 * sparse, 0.32 * sparse)[0],
                       rtol=0, atol=1e-12 * np.abs(want).max())


def test_a_window_must_lie_inside_the_grid():
    sens = SensorArray.grid(1, 1, 0.5e-3, 1e-3, components=("zz",))
    with pytest.raises(ValueError, match="window: expected 2 slices"):
        SensorReadout(SKIN, (N, N), DX, sens, window=(slice(-8, 20), slice(0, 20)))


def test_plane_strain_finger_scan_reads_the_line_kernels():
    n, dx = 256, 20e-6
    gaps = finger_gap((n,), dx, 10e-3)[None]
    sens = SensorArray(positions_m=[[0.0, 0.0], [0.3e-3, 0.0]], depth_m=0.5e-3, components=("zz", "xx"))
    sc = solve_scan(SKIN, gaps, dx, normal_force=100.0, friction=0.5, sensors=sens)
    sol = solve_contact(SKIN, gaps[0], dx, normal_force=100.0, friction=0.5, condition="sliding")
    field = SKIN.stress(sol.load(), [0.5e-3], points=np.array([[0.0], [0.3e-3]]), components=("zz", "xx"))
    want = field.data["stress"].values.reshape(2, 2).T
    assert np.abs(sc.outputs[0][0] - want).max() <= 1e-9 * np.abs(want).max()


def test_more_refusals(monkeypatch):
    g0 = finger_gap((N, N), DX, 10e-3)
    with pytest.raises(ValueError, match="slide_direction: expected a finite non-zero"):
        solve_scan(SKIN, g0[None], DX, normal_force=0.5, friction=0.5, slide_direction=(0.0, 0.0))
    with pytest.raises(ValueError, match="every frame shares one grid"):
        solve_scan(SKIN, lambda i: g0 if i == 0 else g0[:-2], DX, n_frames=2, normal_force=0.5)
    import tactilab.forward.scene_readout as readout

    monkeypatch.setattr(readout, "MAX_WEIGHT_VALUES", 10)
    sens = SensorArray.grid(1, 1, 0.5e-3, 1e-3, components=("zz",))
    with pytest.raises(ValueError, match="GiB of weights, above the limit"):
        SensorReadout(SKIN, (N, N), DX, sens)


def test_a_folded_readout_refuses_a_scan_it_cannot_read():
    sens = SensorArray.grid(1, 1, 0.5e-3, 1e-3, components=("zz",))
    folded = SensorReadout(SKIN, (N, N), DX, sens, loads=("p", "qx", "qy"), sliding=(0.5, (1.0, 0.0)))
    gaps = finger_gap((N, N), DX, 10e-3)[None]
    with pytest.raises(ValueError, match="and partial-slip frames"):
        solve_scan(SKIN, gaps, DX, normal_force=0.5, friction=0.5, slip_ratio=0.5, sensors=folded)
    with pytest.raises(ValueError, match="folds q = 0.5 p along"):
        solve_scan(SKIN, gaps, DX, normal_force=0.5, friction=0.3, sensors=folded)
    sc = solve_scan(SKIN, gaps, DX, normal_force=0.5, friction=0.5, sensors=folded)
    assert sc.outputs[0].shape == (1, 1, 1)
