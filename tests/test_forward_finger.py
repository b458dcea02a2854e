"""Biomimetic finger: receptive fields, scans, fingerprints, Wiener kernels, shape invariance."""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.core import COMPONENTS
from tactilab.data_schemas.recording import Recording
from tactilab.data_schemas.sensors import SensorArray
from tactilab.data_schemas.surface import IsolatedDefect
from tactilab.forward.contact import HertzContact
from tactilab.forward.exploration import (kernel_identification, linear_kernel, shape_invariance,
                                          texture_spectrum, wiener_kernel)
from tactilab.forward.finger import BiomimeticFinger, Fingerprint
from tactilab.forward.halfspace.facade import HalfSpace
from tactilab.forward.halfspace.loads import SurfaceLoad
from tactilab.forward.scanning import scan_outputs, scan_recording, scanned_surface
from tactilab.forward.surfaces import RecordFeature, Surface

COMPS = ("zz", "zx", "xx")


def _bump(x, y, size, height):
    """A raised-cosine bump (data_schemas record) as a surface feature, all in m."""
    return RecordFeature(IsolatedDefect(shape="bump", size_m=size, height_m=height, position_m=(x, y)))


def _finger(friction=0.5, spacing=None, components=("zz",), quantity="stress", **kw):
    sensors = SensorArray.grid(3, 2, 1.5e-3, 3e-3, components=components, quantity=quantity)
    return BiomimeticFinger(HertzContact(0.8), sensors, friction=friction, grid_spacing=spacing, **kw)


@pytest.mark.parametrize("adhesion", [0.0, 0.6])
def test_receptive_field_matches_brute_force_superposition(adhesion):
    """RF (point defect x interfacial stress x point-load response) equals the difference of two
    full forward solves (HalfSpace.stress of the whole contact load with and without a small
    bump-shaped stress concentration), for stress components zz, zx, xx at 6 sensors."""
    f = _finger(spacing=0.04e-3, components=COMPS, adhesion=adhesion)
    x, y = f.grid()
    X, Y = np.meshgrid(x, y)
    h = f.spacing
    p, q = f.traction(X, Y, cell=(h, h))
    bump = _bump(0.0, 0.0, 0.2e-3, 1.0)
    hs = HalfSpace(2e6, 0.5)
    pts = f.sensors.positions_m
    base = hs.stress(SurfaceLoad(p=p, qx=q, spacing=h), 3e-3, points=pts, components=COMPS).data["stress"]
    for u in (-2e-3, 0.5e-3, 2.0e-3):
        m = 1 + bump.height(X + u, Y)
        full = hs.stress(SurfaceLoad(p=p * m, qx=q * m, spacing=h), 3e-3, points=pts, components=COMPS)
        brute = (full.data["stress"] - base).values[0].T  # (sensor, component)
        rf = f.receptive_field([u], 0.0, 0.0, strength=bump.integral())[0]
        assert np.abs(brute - rf).max() < 0.02 * np.abs(rf).max()


def test_scan_equals_receptive_field_for_a_small_defect():
    """The batched scan (one matrix product) minus the flat-surface baseline reproduces the RF."""
    f = _finger(spacing=0.05e-3)
    u = np.linspace(-5e-3, 5e-3, 41)
    bump = _bump(0.0, 0.2e-3, 0.25e-3, 30e-6)
    surf = scanned_surface(bump, u, f)
    flat = scanned_surface([], u, f)
    out = scan_outputs(f, surf, u) - scan_outputs(f, flat, u, reference_height_m=30e-6)
    rf = f.receptive_field(u, 0.0, 0.2e-3, strength=bump.integral() / 30e-6)
    np.testing.assert_allclose(out, rf, atol=0.02 * np.abs(rf).max())


def test_strain_sensors_follow_hooke():
    fs = _finger(components=COMPONENTS)
    fe = _finger(components=("zz", "zx"), quantity="strain")
    u = np.linspace(-3e-3, 3e-3, 7)
    s = fs.receptive_field(u, 0.0, 0.0)
    e = fe.receptive_field(u, 0.0, 0.0)
    tr = s[..., :3].sum(-1)
    np.testing.assert_allclose(e[..., 0], (1.5 * s[..., 2] - 0.5 * tr) / 2e6, rtol=1e-12, atol=1e-30)
    np.testing.assert_allclose(e[..., 1], 1.5 * s[..., 4] / 2e6, rtol=1e-12)  # tensor shear


def test_scan_recording_and_scene_defect_record():
    f = _finger(spacing=0.05e-3)  # resolves the 0.3 mm defect (size / 6)
    defect = IsolatedDefect(shape="bump", size_m=0.3e-3, height_m=50e-6, position_m=(5e-3, 0.0))
    rec = scan_recording(f, defect, speed=0.05, sampling_rate=1000.0, duration=0.2)
    assert isinstance(rec, Recording) and rec.values.shape == (200, 6, 1) and rec.unit == "Pa"
    assert rec.sensor_ids == f.sensors.ids
    u = 0.05 * np.arange(200) / 1000.0
    strength = (0.15e-3) ** 2 * (np.pi / 2 - 2 / np.pi)  # iint h / h_ref dA of the raised-cosine bump
    rf = f.receptive_field(u, 5e-3, 0.0, strength=strength)
    change = rec.values - rec.values[0]  # the defect is out of reach at t = 0
    # 5 %: the finite bump still touches the contact when its centre has just left it (edge)
    np.testing.assert_allclose(change, rf, atol=0.05 * np.abs(rf).max())


def test_fingerprint_puts_a_spectral_peak_at_v_over_lambda(rng):
    """Scheibert et al., Science 323 (2009): ridges of period lambda = 0.5 mm scanned at
    v = 10 cm/s over a random texture give a peak at v / lambda = 200 Hz; smooth skin does not."""
    sensors = SensorArray(positions_m=[[0.0, 0.0]], depth_m=3e-3, components=("zz",))
    seed = int(rng.integers(1 << 30))
    spectra = {}
    for label, fp in (("ridged", Fingerprint(0.5e-3)), ("smooth", None)):
        f = BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, fingerprint=fp, grid_spacing=0.05e-3)
        spectra[label] = texture_spectrum(f, np.random.default_rng(seed), speed=0.1, sampling_rate=2000.0,
                                          duration=0.5, bit_length=0.05e-3)
    fr, ridged = spectra["ridged"]
    band = fr > 30
    assert fr[band][np.argmax(ridged[band])] == pytest.approx(200.0, abs=8.0)
    smooth = spectra["smooth"][1]
    at = np.argmin(np.abs(fr - 200.0))
    assert ridged[at] > 100 * smooth[at]
    assert smooth[at] < smooth[np.argmin(np.abs(fr - 100.0))]  # smooth skin: low-pass, no peak


def test_wiener_kernel_exact_on_a_known_linear_system(rng):
    """Lee--Schetzen on a synthetic FIR system with an m-free random input: error shrinks ~ 1/sqrt(N)."""
    k = np.array([0.0, 1.0, -2.0, 0.5, 0.25])
    errs = []
    for n in (512, 8192, 131072):
        x = rng.choice([-1.0, 1.0], n)
        y = 3.0 + sum(k[m + 2] * np.roll(x, -m) for m in range(-2, 3))
        errs.append(np.linalg.norm(wiener_kernel(x, y, 2) - k) / np.linalg.norm(k))
    assert errs[2] < errs[0] and errs[2] < 0.02


def test_wiener_kernel_of_the_finger_improves_with_record_length(rng):
    """Random square-wave gratings: the first-order Wiener kernel converges to the true kernel
    g1(x) = int p(x, y) g(x - x0, y) dy (binned and continuous), mean error falling with N."""
    sensors = SensorArray(positions_m=[[0.0, 0.0]], depth_m=3e-3, components=("zz",))
    f = BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, grid_spacing=0.2e-3)
    table = kernel_identification(f, rng, bit_length=0.2e-3, record_lengths=(256, 4096, 32768), repeats=4)
    err = table["error_binned"].to_numpy()
    assert err[0] > err[1] > err[2]
    assert err[2] < 0.1 and err[0] > 2 * err[2]
    assert np.all(np.abs(table["error_continuous"] - table["error_binned"]) < 0.05)


def test_linear_kernel_is_pressure_times_point_response():
    f = _finger(friction=0.0)
    xi = np.array([-1e-3, 0.0, 1.3e-3])
    g1 = linear_kernel(f, xi, sensor=2, n_eta=2001)
    a = f.contact.contact_radius
    eta = np.linspace(-a, a, 2001)
    for x, g in zip(xi, g1):
        # a unit defect at world (0, eta) seen from finger position u = -x sits at finger (x, eta)
        rf = np.array([f.receptive_field([-x], 0.0, e, strength=1.0)[0, 2, 0] for e in eta])
        assert g == pytest.approx(np.trapezoid(rf, eta), rel=1e-9)


SCALE_ONLY = ("normal_force", "depth", "y_offset", "speed", "young_modulus", "poisson_ratio", "finger_radius")
SHAPE = ("sensor_x", "friction")


@pytest.mark.parametrize("component", ["zz", "zx"])
def test_shape_invariance_table(component):
    """Measured split (docs/scenes.md), sensor under the contact centre at Z = 3 mm:
    - scale-only parameters keep corr >= 0.99 in the frame scaled by the contact radius (force,
      E, nu and R act through the contact size) and >= 0.97 against raw finger position;
    - the sensor's position relative to the contact changes the shape strongly (corr <= 0.90);
    - friction changes it weakly but clearly: its shape distance 1 - corr is more than twice the
      largest one of any scale-only parameter (in the best frame);
    - speed is exactly invariant (quasi-static), depth and E rescale the gain."""
    table = shape_invariance(component=component)
    best = table[["corr_position", "corr_contact_scaled"]].max(axis=1)
    table = table.assign(distance=1 - best)
    by = table.groupby("parameter")
    scale_only = table[table["parameter"].isin(SCALE_ONLY)]
    assert scale_only["corr_contact_scaled"].min() >= 0.99
    assert scale_only["corr_position"].min() >= 0.97
    assert by.get_group("sensor_x")["corr_position"].max() <= 0.90
    assert by.get_group("friction")["distance"].min() > 2 * scale_only["distance"].max()
    assert by.get_group("speed")["corr_position"].min() > 0.999
    assert 1.3 < by.get_group("depth")["gain"].max() and by.get_group("depth")["gain"].min() < 0.8


def test_bad_input_raises():
    sensors = SensorArray(positions_m=[[0.0, 0.0]], depth_m=3e-3, components=("zz",))
    with pytest.raises(ValueError, match="normal_force: must be finite and > 0"):
        BiomimeticFinger(HertzContact(-1.0), sensors)
    with pytest.raises(ValueError, match="friction: the friction coefficient must be finite and >= 0"):
        BiomimeticFinger(HertzContact(1.0), sensors, friction=-0.2)
    with pytest.raises(ValueError, match="adhesion: must lie in"):
        BiomimeticFinger(HertzContact(1.0), sensors, adhesion=1.5)
    with pytest.raises(ValueError, match="contact: expected a 3-D HertzContact"):
        BiomimeticFinger(HertzContact(100.0, line=True), sensors)
    with pytest.raises(ValueError, match="sensors: expected a data_schemas SensorArray"):
        BiomimeticFinger(HertzContact(1.0), [[0, 0]])
    with pytest.raises(ValueError, match="grid_spacing: must be finite"):
        BiomimeticFinger(HertzContact(1.0), sensors, grid_spacing=0.0)
    with pytest.raises(ValueError, match=r"grid_spacing: 1e-15 m gives \d+ contact-grid nodes per axis .* above the limit"):
        BiomimeticFinger(HertzContact(1.0), sensors, grid_spacing=1e-15)  # was a MemoryError deep in the scan
    with pytest.raises(ValueError, match="fingerprint period"):
        Fingerprint(period=-1.0)
    with pytest.raises(ValueError, match="fingerprint contrast"):
        Fingerprint(contrast=2.0)
    f = BiomimeticFinger(HertzContact(1.0), sensors, friction=0.3)
    with pytest.raises(ValueError, match="speed: a scan time series needs a finger speed > 0"):
        scan_recording(f, IsolatedDefect(size_m=1e-4, height_m=1e-5), speed=0.0, sampling_rate=1e3, duration=0.1)
    with pytest.raises(ValueError, match="sampling_rate: must be finite and > 0"):
        scan_recording(f, IsolatedDefect(size_m=1e-4, height_m=1e-5), speed=0.1, sampling_rate=0.0, duration=0.1)
    with pytest.raises(ValueError, match="duration: must be finite"):
        scan_recording(f, IsolatedDefect(size_m=1e-4, height_m=1e-5), speed=0.1, sampling_rate=1e3, duration=-1)
    with pytest.raises(ValueError, match="duration: .* gives no sample"):
        scan_recording(f, IsolatedDefect(size_m=1e-4, height_m=1e-5), speed=0.1, sampling_rate=1.0, duration=0.5)
    far = IsolatedDefect(size_m=1e-4, height_m=1e-5, position_m=(0.5, 0.0))
    with pytest.raises(ValueError, match="surface: the defect bump at x in .* lies outside the surface strip the scan touches"):
        scan_recording(f, far, speed=0.05, sampling_rate=1e3, duration=0.1)
    with pytest.raises(ValueError, match="surface: expected a surface record or Feature"):
        scanned_surface(3.0, [0.0], f)
    with pytest.raises(ValueError, match="positions: need a non-empty finite"):
        scan_outputs(f, Surface(length=1e-2), [np.nan])
    with pytest.raises(ValueError, match="surface: expected a forward.surfaces.Surface"):
        scan_outputs(f, IsolatedDefect(size_m=1e-4, height_m=1e-5), [0.0])
    with pytest.raises(ValueError, match="batch: frames per product"):
        scan_outputs(f, Surface(length=1e-2), [0.0], batch=0)
    with pytest.raises(ValueError, match="positions: need a finite 1-D"):
        f.receptive_field([[0.0]], 0.0)
    with pytest.raises(ValueError, match="strength: must be finite"):
        f.receptive_field([0.0], 0.0, strength=np.inf)
    with pytest.raises(ValueError, match="sensor: index must be in"):
        linear_kernel(f, [0.0], sensor=3)
    with pytest.raises(ValueError, match="component: index must be in"):
        linear_kernel(f, [0.0], component=1)
    with pytest.raises(ValueError, match="inputs, outputs: need two 1-D arrays"):
        wiener_kernel([1.0, -1.0], [1.0], 0)
    with pytest.raises(ValueError, match="inputs, outputs: contain NaN"):
        wiener_kernel([1.0, np.nan], [1.0, 2.0], 0)
    with pytest.raises(ValueError, match="max_lag: must be an integer"):
        wiener_kernel([1.0, -1.0, 1.0, -1.0], [1.0, 2.0, 3.0, 4.0], 2)
    with pytest.raises(ValueError, match="inputs: constant input"):
        wiener_kernel([1.0, 1.0, 1.0, 1.0], [1.0, 2.0, 3.0, 4.0], 1)
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="rng: expected a numpy.random.Generator"):
        kernel_identification(f, 1)
    with pytest.raises(ValueError, match="noise_std: must be finite and >= 0"):
        kernel_identification(f, rng, noise_std=-1.0)
    with pytest.raises(ValueError, match="bit_length: must be a whole number of grid spacings"):
        kernel_identification(f, rng, bit_length=1.2345e-4)
    with pytest.raises(ValueError, match="repeats: need at least 1"):
        kernel_identification(f, rng, bit_length=f.spacing, repeats=0)
    with pytest.raises(ValueError, match="record_lengths: each must be an integer >"):
        kernel_identification(f, rng, bit_length=f.spacing, record_lengths=(4,))
    with pytest.raises(ValueError, match="variations: unknown parameter 'mass'"):
        shape_invariance(variations={"mass": (1.0,)})
    with pytest.raises(ValueError, match="component: the study reads a 'zz' or 'zx'"):
        shape_invariance(component="xx")


def test_scan_maps_fft_equals_matrix_scan_and_strip_path():
    """Batched DC-FFT maps (kernel FFT once) read at on-node sensors equal the matrix scan; the
    world-strip path (frame step = whole grid spacings) equals the per-frame surface evaluation."""
    from tactilab.forward.scan_maps import ScanMaps

    h = 0.1e-3
    sensors = SensorArray(positions_m=[[0.0, 0.0], [0.5e-3, -0.3e-3], [-1.2e-3, 0.8e-3]], depth_m=2e-3,
                          components=("zz", "zx"))
    f = BiomimeticFinger(HertzContact(0.8), sensors, friction=0.4, adhesion=0.3, grid_spacing=h)
    surface = Surface(length=20e-3, width=20e-3, x_start=-10e-3,
                      features=(_bump(0.3e-3, 0.2e-3, 0.8e-3, 1e-5), _bump(-1e-3, -0.5e-3, 1.2e-3, -5e-6)))
    u = np.arange(-30, 31, 3) * h  # on the grid: strip path
    ref = scan_outputs(f, surface, u)
    sm = ScanMaps(f)
    fft = sm.sensor_values(sm.maps(surface, u, reference_height_m=1e-5))
    np.testing.assert_allclose(fft, ref, atol=1e-9 * np.abs(ref).max())
    off = scan_outputs(f, surface, u + 1e-5 * h)  # off the grid: per-frame evaluation
    np.testing.assert_allclose(off, ref, atol=1e-4 * np.abs(ref).max())
    with pytest.raises(ValueError, match="finger: expected a BiomimeticFinger"):
        ScanMaps("finger")
    with pytest.raises(ValueError, match="positions: need a finite 1-D"):
        sm.maps(surface, [np.nan])
    with pytest.raises(ValueError, match="batch: frames per FFT"):
        sm.maps(surface, [0.0], batch=0)
    far = BiomimeticFinger(HertzContact(0.8), SensorArray(positions_m=[[9e-3, 0.0]], depth_m=2e-3,
                                                          components=("zz",)), grid_spacing=h)
    sm_far = ScanMaps(far)
    with pytest.raises(ValueError, match="sensors: some sensors lie outside the contact grid"):
        sm_far.sensor_values(sm_far.maps(surface, [0.0]))


def test_scene_and_record_guards(monkeypatch, tmp_path):
    from types import SimpleNamespace

    from tactilab.data_schemas.recording import Recording
    from tactilab.data_schemas import recording_io

    with pytest.raises(ValueError, match="scene.contact: the scene has no finger contact"):
        BiomimeticFinger.from_scene(SimpleNamespace(contact=None))
    with pytest.raises(ValueError, match="surface: expected a data_schemas surface record"):
        RecordFeature(object())
    with pytest.raises(ValueError, match="defect_x: must be finite"):
        _finger().receptive_field([0.0], np.nan)
    monkeypatch.setattr(recording_io.importlib.util, "find_spec", lambda name: None)
    rec = Recording(values=np.zeros((2, 1, 1)), sampling_rate_hz=10.0, sensor_ids=("s0",), components=("zz",))
    with pytest.raises(ValueError, match="format: 'parquet' needs the optional package pyarrow"):
        recording_io.write_recording(rec, tmp_path, "parquet")


def test_partial_slip_finger_spans_no_load_to_sliding():
    """slip_ratio: total tangential force = ratio mu F on the node grid; 1 equals sliding."""
    sensors = SensorArray(positions_m=[[0.0, 0.0]], depth_m=3e-3, components=("zx",))
    slide = BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, grid_spacing=0.05e-3)
    x, y = slide.grid()
    X, Y = np.meshgrid(x, y)
    h = slide.spacing
    for ratio in (0.0, 0.4, 1.0):
        f = BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, grid_spacing=h, slip_ratio=ratio)
        p, q = f.traction(X, Y)
        assert q.sum() * h * h == pytest.approx(ratio * 0.4, rel=2e-3, abs=1e-9)
        assert p.sum() * h * h == pytest.approx(0.8, rel=2e-3)
    u = np.linspace(-4e-3, 4e-3, 17)
    np.testing.assert_allclose(f.receptive_field(u, 0.0), slide.receptive_field(u, 0.0), rtol=1e-12, atol=1e-20)
    back = BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, grid_spacing=h, friction_direction=-1.0)
    p_b, q_b = back.traction(X, Y)
    p_f, q_f = slide.traction(X, Y)
    np.testing.assert_array_equal(q_b, -q_f)
    np.testing.assert_array_equal(p_b, p_f)
    with pytest.raises(ValueError, match="friction_direction: must be \\+1"):
        BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, friction_direction=0.5)
    with pytest.raises(ValueError, match="slip_ratio: Q / \\(mu F\\) must lie in"):
        BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, slip_ratio=1.5)
    with pytest.raises(ValueError, match="slip_ratio: partial slip .* give adhesion=0"):
        BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, adhesion=0.5, slip_ratio=0.5)


def test_scan_operators_pass_the_dot_test(rng):
    """<A m, y> = <m, A^T y> for the node-weight operator and the DC-FFT map operator; the map
    operator applied to the unmodulated contact equals the scan's flat-surface outputs."""
    from tactilab.forward.scan_maps import ScanMaps

    sensors = SensorArray.grid(3, 3, 1e-3, 2e-3, components=("zz", "zx"))
    f = BiomimeticFinger(HertzContact(0.8), sensors, friction=0.5, adhesion=0.3, grid_spacing=0.2e-3)
    for A in (f.operator(), ScanMaps(f).operator()):
        m = rng.standard_normal(A.shape[1])
        y = rng.standard_normal(A.shape[0])
        lhs, rhs = (A @ m) @ y, m @ (A.H @ y)
        assert lhs == pytest.approx(rhs, rel=1e-10)
    sm = ScanMaps(f)
    maps = sm.apply(np.ones((sm.n, sm.n)))
    flat = f.operator() @ np.ones(f.operator().shape[1])
    np.testing.assert_allclose(sm.sensor_values(maps[None])[0].ravel(), flat, rtol=1e-9)


def test_memory_guards_give_clear_errors_instead_of_memory_errors(monkeypatch):
    """Each guard replaces a numpy MemoryError (terabytes) found by running `tactilab simulate`
    on scenes with sensors 3 nm deep, 1e6 sensors or 1e9 frames."""
    import tactilab.forward.finger as finger_module
    import tactilab.forward.scanning as scanning

    sensors = SensorArray.grid(2, 1, 1e-3, 3e-9, components=("zz",), quantity="stress")
    with pytest.raises(ValueError, match=r"grid_spacing: the automatic spacing 6e-10 m .* above the limit 2049"):
        BiomimeticFinger(HertzContact(0.8), sensors)
    with pytest.raises(ValueError, match="duration: 1.0 s at 1000000000.0 Hz gives 1000000000 frames, above the limit"):
        scanning.check_scan(0.02, 1e9, 1.0)
    f = _finger(spacing=0.2e-3)
    monkeypatch.setattr(finger_module, "MAX_WORK_VALUES", 100)
    with pytest.raises(ValueError, match=r"sensors: 6 sensors x 1 components over \d+ loaded contact nodes need"):
        f.node_weights()
    monkeypatch.undo()
    monkeypatch.setattr(scanning, "MAX_OUTPUT_VALUES", 10)
    with pytest.raises(ValueError, match=r"positions: 5 frames x 6 outputs .* = 30 values, above the limit 10"):
        scan_outputs(f, Surface(length=2e-2, x_start=-1e-2), np.linspace(-1e-3, 1e-3, 5))


def test_scan_without_the_surface_strip_matches_the_strip(monkeypatch):
    """When the shared surface strip would be too large the scan samples per batch: same outputs."""
    import tactilab.forward.scanning as scanning

    f = _finger(spacing=0.1e-3)
    h = f.spacing
    u = np.arange(-20, 21) * h  # frames on grid nodes: the strip path
    surface = scanned_surface(_bump(0.3e-3, 0.0, 0.5e-3, 20e-6), u, f)
    ref = scan_outputs(f, surface, u)
    monkeypatch.setattr(scanning, "MAX_OUTPUT_VALUES", ref.size)  # outputs fit, the strip does not
    np.testing.assert_allclose(scan_outputs(f, surface, u), ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
