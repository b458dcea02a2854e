"""Tactile metameres: operators, per-mode vs dense analysis, bounds, ambiguity, classes, bad input."""

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.special import ndtr

from tactilab.data_schemas import DisplayDescription
from tactilab.forward import ReceptorHypothesis
from tactilab.inversion import (
    FamilyStimulus,
    GridLoadFamily,
    IndentationFamily,
    SinusoidFamily,
    StimulusFamily,
    TractorFamily,
    compare_stimuli,
    metamer_ambiguity,
    metamer_classes,
    metamer_pair,
    resolvable_subspace,
)
from tactilab.forward import dottest

E = 1.54e6
X = np.linspace(-5e-3, 5e-3, 41)
H2 = ReceptorHypothesis(("xx", "volumetric", "xz"), (1e-3, 2e-3), 1e-4, "engineering")


def _families():
    return [
        (SinusoidFamily(4e-3, 0.2, nu=0.45), X),
        (TractorFamily(np.arange(-4.5, 5, 1.0) * 1e-3, E, nu=0.4, footprint=0.5e-3, limit=300.0), X),
        (GridLoadFamily((24,), 0.2e-3, ("p", "qx"), young_modulus=E), None),
        (GridLoadFamily((24,), 0.2e-3, ("qx", "p"), young_modulus=E, periodic=False), np.linspace(-3e-3, 3e-3, 7)),
        (GridLoadFamily((6, 8), 0.3e-3, ("p", "qx", "qy"), young_modulus=E, nu=0.3), None),
        (IndentationFamily((20,), 0.25e-3, E), None),
    ]


@pytest.mark.parametrize("index", range(6))
def test_every_family_operator_passes_a_dot_test_and_matches_its_matrix_and_strain(index, rng):
    fam, rec = _families()[index]
    assert isinstance(fam, StimulusFamily)
    h = H2 if len(getattr(fam, "shape", (1,))) == 1 else ReceptorHypothesis(("xx", "yz", "xy"), (1e-3,), 1e-4)
    op = fam.operator(h, rec)
    assert dottest(op, rng, rtol=1e-10) < 1e-10
    a = fam.matrix(h, rec)
    n_rec = len(fam.default_receptors() if rec is None else rec)
    assert a.shape == op.shape == (h.n_readouts(n_rec), fam.n_params)
    params = rng.normal(size=fam.n_params)
    np.testing.assert_allclose(op.matvec(params), a @ params, rtol=1e-10, atol=1e-12 * np.abs(a).max())
    # the readout of the full strain (the nonlinear path) agrees with the linear operator
    s = fam.stimulus(params)
    np.testing.assert_allclose(h.readout(s.strain(h.depths, rec)), s.readout(h, rec), rtol=1e-9,
                               atol=1e-12 * np.abs(a).max())


def test_per_mode_analysis_equals_the_dense_one(rng):
    fam = GridLoadFamily((16,), 0.25e-3, ("p", "qx"), young_modulus=E)
    nodes = fam.default_receptors()
    h = "xx,zx@1mm,2mm;noise=1e-5"
    fast = resolvable_subspace(fam, h, 1e3)
    slow = resolvable_subspace(fam, h, 1e3, receptors=nodes[::-1])  # not in grid order: the dense path
    assert fast.wavenumber_edge > 0 and slow.wavenumber_edge is None
    np.testing.assert_allclose(fast.singular_values, slow.singular_values, rtol=1e-9, atol=1e-12)
    s = fast.singular_values
    assert fast.effective_dof == pytest.approx(np.sum(s ** 2 / (1 + s ** 2)))
    assert fast.information_nats == pytest.approx(0.5 * np.sum(np.log1p(s ** 2)))
    assert fast.dimension == slow.dimension == np.sum(s > 1)
    b_fast, b_slow = fast.basis("resolvable"), slow.basis("resolvable")
    np.testing.assert_allclose(b_fast.T @ b_fast, np.eye(b_fast.shape[1]), atol=1e-10)
    np.testing.assert_allclose(b_fast @ b_fast.T, b_slow @ b_slow.T, atol=1e-8)
    null = fast.basis("null")
    assert null.shape[1] == fast.null_dimension
    a = fam.matrix(h)
    assert np.abs(a @ null).max() < 1e-10 * np.abs(a).max()
    # ambiguity: posterior mean and std, per mode vs dense vs a direct Gaussian solve
    target = SinusoidFamily(2e-3).stimulus([2e-6])
    amb = metamer_ambiguity(target, fam, h, 1e3)
    dense = metamer_ambiguity(target, fam, h, 1e3, receptors=nodes[::-1])
    sigma, tau = 1e-5, 1e3
    y = target.readout(h, nodes)
    cov = np.linalg.inv(a.T @ a / sigma ** 2 + np.eye(fam.n_params) / tau ** 2)
    np.testing.assert_allclose(amb.posterior.mean, cov @ a.T @ y / sigma ** 2, rtol=1e-7, atol=1e-9 * tau)
    np.testing.assert_allclose(dense.posterior.mean, amb.posterior.mean, rtol=1e-7, atol=1e-9 * tau)
    np.testing.assert_allclose(amb.posterior.std, np.sqrt(np.diag(cov)), rtol=1e-7)
    np.testing.assert_allclose(dense.posterior.std, np.sqrt(np.diag(cov)), rtol=1e-7)
    assert amb.log_volume_ratio == pytest.approx(-amb.information_nats)
    assert amb.null_energy_fraction == pytest.approx(np.trace(cov) / (tau ** 2 * fam.n_params), rel=1e-9)
    # samples follow the posterior (seeded; 4000 draws: 5 % on the std)
    for a_ in (amb, dense):
        draws = np.array([d.params for d in a_.sample(4000, rng)])
        np.testing.assert_allclose(draws.std(axis=0), np.sqrt(np.diag(cov)), rtol=0.08)
        assert np.abs(draws.mean(axis=0) - amb.posterior.mean).max() < 5 * np.sqrt(np.diag(cov)).max() / np.sqrt(4000)


def test_2d_per_mode_spectrum_and_basis(rng):
    fam = GridLoadFamily((6, 8), 0.3e-3, ("p", "qy"), young_modulus=E)
    h = "zz,yz@1mm;noise=1e-5"
    fast = resolvable_subspace(fam, h, 1e3)
    slow = resolvable_subspace(fam, h, 1e3, receptors=fam.default_receptors()[::-1])
    np.testing.assert_allclose(fast.singular_values, slow.singular_values, rtol=1e-9, atol=1e-12)
    b = fast.basis("resolvable")
    assert b.shape == (fam.n_params, fast.dimension)
    np.testing.assert_allclose(b.T @ b, np.eye(b.shape[1]), atol=1e-10)
    bs = slow.basis("resolvable")
    np.testing.assert_allclose(b @ b.T, bs @ bs.T, atol=1e-8)
    target = fam.stimulus(rng.normal(size=fam.n_params) * 1e3)
    amb = metamer_ambiguity(target, fam, h, 1e3)
    dense = metamer_ambiguity(target, fam, h, 1e3, receptors=fam.default_receptors()[::-1])
    np.testing.assert_allclose(amb.posterior.mean, dense.posterior.mean, rtol=1e-7, atol=1e-6)
    np.testing.assert_allclose(amb.posterior.std, dense.posterior.std, rtol=1e-7)
    draws = np.array([d.params for d in amb.sample(3000, rng)])
    np.testing.assert_allclose(draws.std(axis=0).mean(), amb.posterior.std.mean(), rtol=0.05)
    other = GridLoadFamily((6, 8), 0.3e-3, ("qx",), young_modulus=E)
    fast_pair = metamer_pair(target, other, h, rcond=1e-8)
    slow_pair = metamer_pair(target, other, h, fam.default_receptors()[::-1], rcond=1e-8)
    assert fast_pair.relative_residual == pytest.approx(slow_pair.relative_residual, rel=1e-8)
    np.testing.assert_allclose(fast_pair.params, slow_pair.params, rtol=1e-6, atol=1e-8 * np.abs(slow_pair.params).max())


def test_metamer_pair_fields_and_per_mode_solve_equals_dense(rng):
    fam = GridLoadFamily((32,), 0.25e-3, ("qx",), young_modulus=E)
    nodes = fam.default_receptors()
    target = IndentationFamily((32,), 0.25e-3, E).stimulus(rng.normal(size=32) * 1e-6)
    h = ReceptorHypothesis(("xx", "zx"), (1e-3, 2e-3), 2e-4)
    pair = metamer_pair(target, fam, h, rcond=1e-8)
    dense = metamer_pair(target, fam, h, nodes[::-1], rcond=1e-8)
    assert pair.relative_residual == pytest.approx(dense.relative_residual, rel=1e-8)
    np.testing.assert_allclose(pair.params, dense.params, rtol=1e-6, atol=1e-9 * np.abs(dense.params).max())
    diff = np.linalg.norm(pair.match_readout - pair.target_readout)
    assert pair.relative_residual == pytest.approx(diff / np.linalg.norm(pair.target_readout))
    assert pair.explained == pytest.approx(1 - pair.relative_residual ** 2)
    assert pair.dprime == pytest.approx(diff / 2e-4)
    assert pair.chi2 == pytest.approx(pair.dprime ** 2)
    assert pair.p_correct_2ifc == pytest.approx(ndtr(pair.dprime / np.sqrt(2)))
    assert pair.metameric == (pair.dprime < 1.0)
    assert pair.dof == dense.dof == pair.target_readout.size - fam.n_params  # zx sees every mode of q_x
    assert set(pair.per_component) == {"xx", "zx"}
    score = pair.evaluate(h)
    assert score.relative_residual == pytest.approx(pair.relative_residual) and score.dprime == pytest.approx(pair.dprime)
    ds = pair.to_dataset()
    assert ds["target"].shape == (2, 2, 32) and ds.attrs["hypothesis"] == str(h)
    quiet = metamer_pair(target, fam, "xx,zx@1mm,2mm", rcond=1e-8)
    assert quiet.dprime is None and quiet.p_correct_2ifc is None and quiet.chi2 is None and quiet.metameric is None
    assert quiet.scan_rms is None


def test_bounds_are_respected_and_optimal():
    fam = TractorFamily(np.array([-9, -7, -5, -3, -1, 1, 3, 5, 7, 9]) * 1e-3, E, limit=600.0)
    target = SinusoidFamily(4e-3, 0.0).stimulus([0.5e-3])
    h = "xx,zx@1.25mm"
    bounded = metamer_pair(target, fam, h, X)
    free = metamer_pair(target, fam, h, X, bounds=None)
    assert np.abs(bounded.params).max() <= 600.0 * (1 + 1e-12)
    assert np.abs(free.params).max() > 600.0 and bounded.relative_residual > free.relative_residual
    a, b = fam.matrix(h, X), bounded.target_readout
    ref = minimize(lambda q: np.sum((a @ q - b) ** 2) * 1e4, np.zeros(10), jac=lambda q: 2e4 * a.T @ (a @ q - b),
                   bounds=[(-600, 600)] * 10, method="L-BFGS-B", options={"ftol": 1e-15, "gtol": 1e-12, "maxiter": 5000})
    assert bounded.relative_residual <= np.linalg.norm(a @ ref.x - b) / np.linalg.norm(b) * (1 + 1e-6)
    explicit = metamer_pair(target, fam, h, X, bounds=(-100.0, 100.0))
    assert np.abs(explicit.params).max() <= 100.0 * (1 + 1e-12)


def test_from_display_uses_the_row_and_its_limits():
    disp = DisplayDescription.wh2008()
    fam = TractorFamily.from_display(disp, E)
    np.testing.assert_allclose(fam.tractor_x, np.array([-9, -7, -5, -3, -1, 1, 3, 5, 7, 9]) * 1e-3)
    assert fam.limit == pytest.approx(disp.max_traction_pa * disp.tractor_width_m)
    assert fam.footprint == disp.tractor_width_m
    with pytest.raises(ValueError, match=r"row: must be an integer in \[0, 0\]"):
        TractorFamily.from_display(disp, E, row=1)


def test_nonlinear_hypotheses_refine_the_linear_match():
    fam = TractorFamily(np.arange(-4.5, 5, 1.0) * 1e-3, E)
    target = SinusoidFamily(4e-3, 0.7).stimulus([0.1e-3])
    h = "max_shear,von_mises@1.25mm;noise=1e-4"
    pair = metamer_pair(target, fam, h, X)
    start = metamer_pair(target, fam, "xx,yy,zz,yz,zx,xy@1.25mm", X)
    before = compare_stimuli(target, start.match, h, X)
    assert pair.relative_residual <= before.relative_residual + 1e-12
    assert pair.dprime == pytest.approx(np.linalg.norm(pair.match_readout - pair.target_readout) / 1e-4)


def test_compare_and_classes():
    fam = TractorFamily([-1e-3, 1e-3], E)
    h = ReceptorHypothesis(("xx", "zx"), (1.25e-3,), 1e-4)
    a, b, c = fam.stimulus([-10.0, 10.0]), fam.stimulus([-10.001, 10.0]), fam.stimulus([10.0, -10.0])
    score = compare_stimuli(a, b, h, X)
    ra, rb = a.readout(h, X), b.readout(h, X)
    assert score.dprime == pytest.approx(np.linalg.norm(ra - rb) / 1e-4) and score.metameric
    assert not compare_stimuli(a, c, h, X).metameric
    classes = metamer_classes([a, b, c, fam.stimulus([-10.0, 10.002])], h, X)
    assert classes.labels[0] == classes.labels[1] == classes.labels[3] != classes.labels[2]
    assert classes.dprime.shape == (4, 4) and np.allclose(classes.dprime, classes.dprime.T)
    assert classes.dprime[0, 1] == pytest.approx(score.dprime, rel=1e-6)


def test_plots_write_pngs(tmp_path):
    fam = GridLoadFamily((32,), 0.25e-3, ("p", "qx"), young_modulus=E)
    sub = resolvable_subspace(fam, "xx,zx@1mm;noise=1e-4", 1e3)
    sub.plot(tmp_path / "spectrum.png")
    pair = metamer_pair(SinusoidFamily(4e-3).stimulus([1e-5]), TractorFamily([-1e-3, 1e-3], E), "xx,zx@1mm", X)
    pair.plot(tmp_path / "pair.png")
    assert (tmp_path / "spectrum.png").stat().st_size > 1000 and (tmp_path / "pair.png").stat().st_size > 1000


PERIODIC = GridLoadFamily((16,), 0.25e-3, ("p",), young_modulus=E)
SINE = SinusoidFamily(4e-3).stimulus([1e-5])


@pytest.mark.parametrize("call,match", [
    (lambda: ReceptorHypothesis.parse("xx,shear@1mm"), "components: unknown component 'shear'"),
    (lambda: ReceptorHypothesis(("xx",), (1e-3,), noise_std=0.0), "noise_std: must be finite and > 0"),
    (lambda: resolvable_subspace(PERIODIC, "max_shear@1mm;noise=1e-3", 1.0),
     r"hypothesis: 'max_shear@1mm;noise=0.001' holds nonlinear invariants.*resolvable_subspace need linear"),
    (lambda: resolvable_subspace(PERIODIC, "xx@1mm", 1.0), "hypothesis: resolvable_subspace needs noise_std"),
    (lambda: resolvable_subspace(PERIODIC, "xx@1mm;noise=1e-3", 0.0), "prior_std: must be finite and > 0"),
    (lambda: resolvable_subspace(PERIODIC, "xx@1mm;noise=1e-3", "big"), "prior_std: expected one number"),
    (lambda: metamer_pair(SINE, PERIODIC, "xx@1mm", [0.1e-3]), "receptors: off the grid of a periodic family"),
    (lambda: PERIODIC.operator("xx@1mm", np.zeros((3, 2))), r"receptors: the 1-D grid load family needs"),
    (lambda: PERIODIC.stimulus(np.zeros(15)), r"params: the grid load family takes 16 parameters \(Pa\), got 15"),
    (lambda: PERIODIC.stimulus(np.full(16, np.nan)), "params: must be finite"),
    (lambda: SinusoidFamily(4e-3).stimulus([1e-5]).readout("xx@1mm"), "receptors: the sinusoid family has no grid"),
    (lambda: SinusoidFamily(4e-3).matrix("xx@1mm", np.zeros((3, 2))), "receptors: the sinusoid family is a plane"),
    (lambda: metamer_pair(SINE, TractorFamily([0.0], E), "xx@1mm"), "receptors: none of the families has a grid"),
    (lambda: metamer_pair(SINE, PERIODIC, "xx@1mm", criterion=0), "criterion: the d' threshold must be"),
    (lambda: metamer_pair(SINE, PERIODIC, "xx@1mm", rcond=2.0), r"rcond: must be in \[0, 1\)"),
    (lambda: metamer_pair(SINE, PERIODIC, "xx@1mm", bounds=(1.0, -1.0)), "bounds: need lower <= upper"),
    (lambda: metamer_pair(PERIODIC.stimulus(np.arange(16.0)), PERIODIC, "xx@1mm", scan_phases=[0.0]),
     "scan_phases: a travelling scan needs a SinusoidFamily target"),
    (lambda: metamer_pair(SINE, PERIODIC, "xx@1mm", scan_phases=[np.nan]), "scan_phases: give finite phases"),
    (lambda: metamer_pair("bump", PERIODIC, "xx@1mm"), "target: expected a FamilyStimulus"),
    (lambda: metamer_pair(SINE, PERIODIC, 3), "hypothesis: expected a ReceptorHypothesis or a string"),
    (lambda: PERIODIC.matrix("max_shear@1mm"), "hypothesis: 'max_shear@1mm' holds nonlinear invariants"),
    (lambda: IndentationFamily((8,), 1e-4, E, periodic=False), "periodic: IndentationFamily needs periodic=True"),
    (lambda: GridLoadFamily((8,), 1e-4), "young_modulus: required, in Pa"),
    (lambda: GridLoadFamily((8,), 1e-4, ("px",), young_modulus=E), "loads: give distinct names"),
    (lambda: GridLoadFamily((8,), 1e-4, young_modulus=E, periodic=False).modes("xx@1mm"),
     "modes: the grid load family is not periodic"),
    (lambda: TractorFamily([], E), "tractor_x: give finite tractor centres"),
    (lambda: TractorFamily([0.0], -1.0), "young_modulus: Young's modulus must be finite and > 0 Pa"),
    (lambda: TractorFamily([0.0], E, footprint=-1.0), "footprint: must be finite and >= 0 m"),
    (lambda: TractorFamily([0.0], E, limit=0.0), "limit: must be finite and > 0 N/m"),
    (lambda: SinusoidFamily(0.0), "pitch: must be finite and > 0 m"),
    (lambda: SinusoidFamily(1e-3, phase=np.inf), "phase: must be finite"),
    (lambda: SINE.strain([0.0], X), "depths: must be finite and > 0 m"),
    (lambda: resolvable_subspace(PERIODIC, "xx@1mm;noise=1e-3", 1.0).basis("both"),
     "which: must be 'resolvable' or 'null'"),
    (lambda: metamer_ambiguity(SINE, PERIODIC, "xx@1mm;noise=1e-3", 1.0).sample(0, np.random.default_rng(0)),
     "n: number of samples must be an integer >= 1"),
    (lambda: metamer_ambiguity(SINE, PERIODIC, "xx@1mm;noise=1e-3", 1.0).sample(2, 1), "rng: expected a numpy Generator"),
    (lambda: metamer_ambiguity("bump", PERIODIC, "xx@1mm;noise=1e-3", 1.0), "target: expected a FamilyStimulus"),
    (lambda: metamer_classes([SINE, SINE], "xx@1mm", X), "hypothesis: metamer classes need noise_std"),
    (lambda: metamer_classes([SINE], "xx@1mm;noise=1e-3", X), "stimuli: give at least two stimuli"),
    (lambda: compare_stimuli(SINE, 1.0, "xx@1mm", X), "b: expected a FamilyStimulus"),
    (lambda: FamilyStimulus(PERIODIC, np.zeros(3)), "params: the grid load family takes 16"),
])
def test_bad_input_is_named(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_a_hypothesis_that_reads_nothing_of_the_target_is_refused_not_called_metameric():
    """Volumetric strain at nu = 1/2 is 0 for every surface traction: the residual would be 0/0 and
    every stimulus 'metameric'; metamer_pair refuses instead (it used to answer residual 0, True)."""
    target = SinusoidFamily(4e-3).stimulus([5e-4])
    fam = TractorFamily(np.array([-9, -7, -5, -3, -1, 1, 3, 5, 7, 9]) * 1e-3, E, limit=600.0)
    x = np.linspace(-5e-3, 5e-3, 201)
    with pytest.raises(ValueError, match=r"reads exactly 0 of the target .* no metamer to find"):
        metamer_pair(target, fam, "volumetric@1.25mm;noise=1e-3", x)
    assert metamer_pair(target, fam, "xx,zx@1.25mm;noise=1e-3", x).relative_residual > 0
