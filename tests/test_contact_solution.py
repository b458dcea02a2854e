"""solve_contact: friction (full sliding), the result object, warnings and input rules."""

import math
import warnings

import numpy as np
import pytest

from contact_oracles import check_complementarity, ellipse, grid, hertz_sphere
from tactilab.forward import AccuracyWarning, ContactSolution, HalfSpace, solve_contact
from tactilab.forward.contact import ContactCompliance, memory_estimate

E, R, F = 1.0e6, 0.01, 0.5
TOL = 1e-8


def sphere(n, nu=0.5, cover=3.0):
    a, _ = hertz_sphere(F, R, E / (1 - nu**2))
    h = cover * a / n
    x = grid(n, h)
    X, Y = np.meshgrid(x, x)
    return (X**2 + Y**2) / (2 * R), h


def test_full_sliding_at_half_is_mu_p_and_the_frictionless_pressure():
    skin = HalfSpace(E, 0.5)
    g0, h = sphere(40)
    free = solve_contact(skin, g0, h, normal_force=F)
    slide = solve_contact(skin, g0, h, normal_force=F, friction=0.4, condition="sliding", slide_direction=(0.6, -0.8))
    assert np.array_equal(slide.pressure, free.pressure)
    assert np.array_equal(slide.qx, 0.4 * 0.6 * slide.pressure)
    assert np.array_equal(slide.qy, -0.4 * 0.8 * slide.pressure)
    assert slide.coupling == {"force": 0.0, "area": 0.0}
    assert slide.slip.sum() == slide.contact.sum() and not slide.stick.any()
    assert free.qx.max() == 0 and free.condition == "frictionless"


def test_full_sliding_plane_strain_sign():
    skin = HalfSpace(E, 0.5)
    n, h = 128, 2e-5
    x = grid(n, h)
    sol = solve_contact(skin, x**2 / (2 * R), h, normal_force=50.0, friction=0.5, condition="sliding",
                        slide_direction=(-1.0, 0.0))
    assert np.array_equal(sol.qx, -0.5 * sol.pressure) and sol.qy is None


@pytest.mark.parametrize("nu", [0.3, 0.0])
def test_sliding_coupling_below_half(nu):
    """At nu < 1/2, q = mu p moves the surface normally; the pressure is the fixed point with that displacement."""
    skin = HalfSpace(E, nu)
    g0, h = sphere(48, nu)
    mu = 0.6
    free = solve_contact(skin, g0, h, normal_force=F)
    sol = solve_contact(skin, g0, h, normal_force=F, friction=mu, condition="sliding")
    assert np.array_equal(sol.qx, mu * sol.pressure)
    C = ContactCompliance(skin, g0.shape, h, periodic=False)
    gap = g0 + C.normal(sol.pressure) + C.normal_from_tangential(sol.qx, sol.qy) - sol.approach
    p = sol.pressure
    assert gap[p > 0].__abs__().max() <= 10 * TOL * np.ptp(g0) and gap.min() >= -10 * TOL * np.ptp(g0)
    assert sol.coupling["force"] == pytest.approx(0.0, abs=1e-12)  # force control: the force is kept
    assert sol.coupling["area"] != 0.0
    # qx > 0 on the skin pushes the surface ahead of it (x > 0) into the skin and lifts it behind
    # (Cerruti; by reciprocity Boussinesq's inward radial displacement): the pressure moves to -x
    x = grid(48, h)
    shift = (sol.pressure.sum(0) @ x - free.pressure.sum(0) @ x) / sol.pressure.sum()
    assert -3 * h < shift < 0


def test_load_carries_the_contact_error_into_fields():
    skin = HalfSpace(E, 0.5)
    g0, h = sphere(32)
    sol = solve_contact(skin, g0, h, normal_force=F, friction=0.3, condition="sliding")
    load = sol.load()
    assert load.spacing == sol.spacing and load.periodic is False
    assert load.error_estimate == sol.error_estimate > 0
    field = skin.stress(load, depth=1e-3, components=("zz",))
    assert field.data.attrs["error_covers"] == "method+load"
    exact = skin.stress(ContactSolutionLoad(sol), depth=1e-3, components=("zz",))
    assert field.error_estimate >= sol.error_estimate * 0.5 + exact.error_estimate


def ContactSolutionLoad(sol):
    """The same tractions without the contact's error (what a field's own method error would be)."""
    from tactilab.forward import SurfaceLoad

    return SurfaceLoad(p=sol.pressure, qx=sol.qx, qy=sol.qy, spacing=sol.spacing)


def test_dataset_and_plot(tmp_path):
    skin = HalfSpace(E, 0.5)
    g0, h = sphere(32)
    sol = solve_contact(skin, g0, h, normal_force=F, friction=0.3, condition="sliding")
    ds = sol.to_dataset()
    assert ds["pressure"].attrs["units"] == "Pa" and ds["x"].attrs["units"] == "m"
    assert "long_name" in ds["qx"].attrs and ds["contact"].dtype == np.uint8
    assert ds.attrs["normal_force"] == pytest.approx(F) and ds.attrs["error_solver"] >= 0
    png = sol.plot(tmp_path / "c.png")
    assert png.stat().st_size > 10_000
    n = 128
    x = grid(n, 2e-5)
    line = solve_contact(skin, x**2 / (2 * R), 2e-5, normal_force=50.0)
    assert line.to_dataset()["pressure"].dims == ("x",)
    assert line.plot(tmp_path / "l.png").stat().st_size > 5_000
    assert "ContactSolution(shape=(128,)" in repr(line)


def test_small_contact_warns_with_the_spacing_that_would_do():
    skin = HalfSpace(E, 0.5)
    g0, h = sphere(32, cover=12.0)  # the contact spans about 5 nodes
    with pytest.warns(AccuracyWarning, match=r"spans only .* a spacing of .* m or finer"):
        solve_contact(skin, g0, h, normal_force=F)


def test_approach_below_the_gap_gives_an_empty_contact():
    skin = HalfSpace(E, 0.5)
    g0, h = sphere(16)
    with pytest.warns(UserWarning, match="nothing touches"):
        sol = solve_contact(skin, g0 + 1e-6, h, approach=0.5e-6)
    assert sol.normal_force == 0 and not sol.contact.any() and sol.gap.min() == pytest.approx(0.5e-6)


def test_not_converged_warns():
    skin = HalfSpace(E, 0.5)
    g0, h = sphere(32)
    with pytest.warns(AccuracyWarning, match="max_iter: the solver stopped after"):
        sol = solve_contact(skin, g0, h, normal_force=F, max_iter=2)
    assert not sol.converged


def test_memory_estimate_grows_with_the_padded_grid():
    assert memory_estimate((1024, 1024), False, "frictionless") < 600 * 2**20
    assert memory_estimate((64, 64), False, "frictionless") > memory_estimate((64, 64), True, "frictionless")


BAD = [
    (dict(gap=np.array([[0.0, np.nan], [1.0, 1.0]] * 4)), "gap: must be finite"),
    (dict(normal_force=1.0, approach=1e-6), "give exactly one, got"),
    (dict(normal_force=None), "give exactly one, got none"),
    (dict(normal_force=-1.0), "normal_force: must be finite and > 0 N"),
    (dict(friction=-0.1), "friction: the Coulomb coefficient must be >= 0"),
    (dict(friction=math.nan), "friction: the Coulomb coefficient must be >= 0"),
    (dict(friction="0.5"), "friction: the Coulomb coefficient must be >= 0"),
    (dict(normal_force=None, approach=math.nan), "approach: must be finite, got nan; give a finite number in m"),
    (dict(friction=math.inf, condition="sliding"), r"friction: .*inf only for condition='stuck'"),
    (dict(friction=0.2, condition="partial", tangential_force=(0.2, 0.0)), r"tangential_force: \|Q\| = 0.2 exceeds"),
    (dict(normal_force=None, mean_pressure=1e3), "mean_pressure: is the load of a periodic cell"),
    (dict(normal_force=None, approach=1e-6, periodic=True), "approach: a periodic contact has no defined approach"),
    (dict(gap=np.broadcast_to(0.0, (200_000, 200_000))), r"gap: .* needs about .* GiB, above the limit"),
    (dict(gap=np.zeros((9, 9)), periodic=True), "gap: a periodic grid needs an even number of nodes"),
    (dict(gap=np.zeros((2, 2, 2))), r"gap: expected shape \(nx,\)"),
    (dict(condition="glued"), "condition: must be one of"),
    (dict(tangential_force=0.1), "tangential_force: is for condition 'partial' or 'stuck'"),
    (dict(condition="partial", friction=0.5), "tangential_force: condition='partial' needs"),
    (dict(condition="sliding"), "friction: condition='sliding' needs friction > 0"),
    (dict(slide_direction=(0.0, 0.0)), "slide_direction: expected a non-zero"),
    (dict(tol=2.0), r"tol: must be a relative tolerance in \(0, 1\)"),
    (dict(max_iter=0), "max_iter: must be a positive integer"),
    (dict(method="newton"), "method: must be 'auto'"),
    (dict(initial="cold"), "initial: must be a ContactSolution of the same shape"),
    (dict(skin=object()), "skin: needs a surface_compliance"),
    (dict(periodic=1), "periodic: must be True or False"),
    (dict(spacing=-1.0), "spacing: grid spacing must be finite and > 0 m"),
]


@pytest.mark.parametrize("kwargs,match", BAD, ids=[m for _, m in BAD])
def test_bad_input(kwargs, match):
    g0, h = sphere(16)
    args = dict(skin=HalfSpace(E, 0.5), gap=g0, spacing=h, normal_force=F)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        solve_contact(args.pop("skin"), args.pop("gap"), args.pop("spacing"), **args)


def test_plane_strain_slides_along_x_only():
    with pytest.raises(ValueError, match="slide_direction: a plane-strain contact slides along x only"):
        solve_contact(HalfSpace(E, 0.5), np.linspace(0, 1e-6, 16), 1e-5, normal_force=1.0, friction=0.3,
                      condition="sliding", slide_direction=(0.0, 1.0))


def test_solution_is_read_only():
    g0, h = sphere(16)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        sol = solve_contact(HalfSpace(E, 0.5), g0, h, normal_force=F)
    assert isinstance(sol, ContactSolution)
    with pytest.raises(ValueError, match="read-only"):
        sol.pressure[0, 0] = 1.0
    check_complementarity(sol, g0, TOL)
    assert sol.area == pytest.approx(sol.contact.sum() * h * h)
    assert ellipse(np.array([0.0]), 1.0, 2.0)[0] == 2.0


def test_grid_operators_are_reused_for_an_equal_skin():
    from tactilab.forward.contact import solve as solve_module

    g0, h = sphere(16)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        solve_contact(HalfSpace(E, 0.5), g0, h, normal_force=F)
        first = list(solve_module._OPERATORS.values())
        solve_contact(HalfSpace(E, 0.5), g0, h, normal_force=F)  # a new, equal skin
        assert list(solve_module._OPERATORS.values()) == first
        solve_contact(HalfSpace(E, 0.4), g0, h, normal_force=F)  # another skin: new operators
    assert all(op.skin.nu == 0.4 for op in solve_module._OPERATORS.values())
