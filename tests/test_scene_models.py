"""Scenes through the solved contact: the interface models and the auto choice (forward/scene_models.py).

Oracles: Westergaard's closed-form pressure of a sinusoid pressed by a flat (Johnson, Contact
Mechanics, 13.3; K. L. Johnson, J. A. Greenwood, J. G. Higginson, Int. J. Mech. Sci. 27, 1985),
its strain at depth by the periodic half-space transfer on a grid 16 times finer; full contact,
where the linear superposition is the exact answer; a finger that does not move, a static press."""

import math

import numpy as np
import pytest

from tactilab.data_schemas import SensorArray, SkinMaterial
from tactilab.data_schemas.scene import Contact, Scan, Scene
from tactilab.data_schemas.surface import IsolatedDefect, SinusoidalGrating
from tactilab.forward import HalfSpace, SurfaceLoad, solve_contact
from tactilab.forward.scanning import scan_outputs
from tactilab.forward.scene_frames import SceneFrames
from tactilab.forward.scene_models import contact_tol, run_model, scene_signals, signal_error

E, NU = 1e6, 0.5
E_STAR = E / (1 - NU**2)
L, A, PHASE = 1e-3, 2e-6, 0.3
K = 2 * math.pi / L
P_STAR = math.pi * E_STAR * A / L  # Westergaard: full contact at and above this mean pressure
SENSORS = SensorArray(positions_m=[[0.0, 0.0], [0.25e-3, 0.0], [-0.1e-3, 0.0]], depth_m=0.3e-3, quantity="strain",
                      components=("zz", "zx", "xx"))
MU = 0.3


def _cell(ratio, model="exact", tol=1e-2, **scan):
    scan = dict(dict(speed_m_per_s=0.01, duration_s=0.004, sampling_rate_hz=1000, start_position_m=0.1e-3), **scan)
    return Scene(material=SkinMaterial(young_modulus_pa=E, poisson_ratio=NU),
                 surface=SinusoidalGrating(period_m=L, amplitude_m=A, phase_rad=PHASE),
                 contact=Contact(mean_pressure_pa=ratio * P_STAR, friction_coefficient=MU, model=model, tol=tol),
                 sensors=SENSORS, scan=Scan(**scan))


def westergaard(x, p_bar):
    """The pressure of a sinusoid h = A cos(k x) pressed by a flat at mean pressure p_bar, x from a crest."""
    s2 = p_bar / P_STAR
    if s2 >= 1:
        return p_bar + P_STAR * np.cos(K * x)
    sa = np.sin(math.pi * x / L) ** 2
    return np.where(sa < s2, 2 * p_bar * np.cos(math.pi * x / L) / s2 * np.sqrt(np.clip(s2 - sa, 0, None)), 0.0)


def westergaard_signals(scene):
    m = 4096
    xs = (np.arange(m) - m // 2) * L / m
    out = []
    for u in scene.scan.positions_m:
        crest = (math.pi / 2 - PHASE) / K - u  # finger-frame x of the crest under the cell
        p = westergaard((xs - crest + L / 2) % L - L / 2, scene.contact.mean_pressure_pa)
        load = SurfaceLoad(p=p, qx=MU * p, spacing=L / m, periodic=True)  # nu = 1/2: sliding is q = mu p
        f = HalfSpace(E, NU).strain(load, [SENSORS.depth_m], points=SENSORS.positions_m[:, :1],
                                    components=SENSORS.components)
        out.append(f.data["strain"].values.reshape(3, 3).T)
    return np.array(out)


@pytest.mark.parametrize("ratio", [0.05, 0.2, 0.5, 1.0, 2.0])
def test_exact_periodic_cell_equals_westergaard_at_depth(ratio):
    scene = _cell(ratio)
    values, info = scene_signals(scene)
    want = westergaard_signals(scene)
    assert info["model"] == "exact"
    assert np.abs(values - want).max() <= 3e-4 * np.abs(want).max()  # measured 7e-5 at 0.05, 6e-16 in full contact


@pytest.mark.parametrize("ratio", [0.05, 0.3, 2.0])
def test_auto_picks_exact_where_the_cheap_models_miss_tol_and_reports_errors_that_cover_them(ratio):
    scene = _cell(ratio, model="auto")
    values, info = scene_signals(scene)
    exact = westergaard_signals(scene)
    frames = info["frames"]
    true = {m: signal_error(run_model(frames, m).values, exact) for m in ("linear", "modulation")}
    want = "exact" if ratio < 1 else "linear"
    assert info["model"] == want, info["reason"]
    for m, err in true.items():
        assert info["errors"][m] >= 0.99 * err, (m, info["errors"], true)
    assert true["linear"] > 1e-2 if ratio < 1 else true["linear"] < 1e-10
    assert "p_bar/p* = " in info["reason"]


def test_exact_equals_the_modulation_at_its_one_load_ratio():
    """The modulation M = 1 + h / A of a sinusoid is Westergaard's full-contact pressure exactly at p_bar = p*."""
    scene = _cell(1.0, model="modulation")
    values, _ = scene_signals(scene)
    assert np.abs(values - westergaard_signals(scene)).max() <= 1e-9 * np.abs(values).max()


def _finger(surface, model="auto", tol=0.05, speed=0.01, duration=0.01, **contact):
    return Scene(material=SkinMaterial(young_modulus_pa=E, poisson_ratio=NU), surface=surface,
                 contact=Contact(normal_force_n=1.0, finger_radius_m=0.01, friction_coefficient=0.5, model=model,
                                 tol=tol, **contact),
                 sensors=SensorArray.grid(3, 1, 0.4e-3, 0.5e-3, quantity="strain", components=("zz", "zx")),
                 scan=Scan(speed_m_per_s=speed, duration_s=duration, sampling_rate_hz=2000))


def test_full_contact_finger_exact_and_linear_agree_and_auto_picks_linear():
    shallow = SinusoidalGrating(period_m=0.5e-3, amplitude_m=0.1e-6)
    values, info = scene_signals(_finger(shallow))
    exact, _ = scene_signals(_finger(shallow, model="exact"))
    linear, _ = scene_signals(_finger(shallow, model="linear"))
    assert info["model"] == "linear", info["reason"]
    assert signal_error(linear, exact) <= 0.05
    assert info["pressures"]["ratio"] > 1
    assert info["errors"]["linear"] >= signal_error(linear, exact)


def test_the_modulation_on_the_contact_grid_is_todays_scan():
    bump = IsolatedDefect(shape="bump", size_m=0.4e-3, height_m=2e-6, position_m=(0.05e-3, 0.0))
    scene = _finger(bump, model="modulation")
    values, info = scene_signals(scene)
    frames = info["frames"]
    from tactilab.forward.scanning import scanned_surface

    finger = frames.finger
    surf = scanned_surface(bump, frames.positions, finger)
    want = scan_outputs(finger, surf, frames.positions)
    assert np.abs(values - want).max() <= 1e-9 * np.abs(want).max()


def test_a_finger_that_does_not_move_is_a_static_press():
    bump = IsolatedDefect(shape="bump", size_m=0.4e-3, height_m=2e-6)
    scene = _finger(bump, model="exact", speed=0.0, duration=0.0015, adhesion=0.4)
    values, info = scene_signals(scene)
    frames = info["frames"]
    sol = solve_contact(frames.skin, frames.gap(0), frames.spacing, normal_force=1.0, friction=0.5,
                        condition="partial", tangential_force=(0.4 * 0.5 * 1.0, 0.0), tol=contact_tol(frames))
    p = sol.pressure[None]
    want = frames.readout().read(p, sol.qx[None], sol.qy[None])[0][0]
    assert np.allclose(values, want[None], rtol=0, atol=1e-7 * np.abs(want).max())


def test_adhesion_of_a_sliding_finger_is_said_to_be_unused_by_the_solved_contact():
    bump = IsolatedDefect(shape="bump", size_m=0.4e-3, height_m=2e-6)
    with pytest.warns(UserWarning, match=r"contact.adhesion: 0.4 is not used by the solved contact .* sliding at "
                                         r"10 mm/s, which is in full sliding"):
        SceneFrames.from_scene(_finger(bump, model="exact", adhesion=0.4))


def test_the_onset_starts_without_tangential_load():
    bump = IsolatedDefect(shape="bump", size_m=0.4e-3, height_m=2e-6)
    base = _finger(bump, model="exact")
    onset = base.model_copy(update={"scan": base.scan.model_copy(update={"onset_s": 0.004})})
    assert np.allclose(onset.scan.slip_ratios[:9], np.arange(9) / 2000 / 0.004)
    ramp = run_model(SceneFrames.from_scene(onset), "exact", [0])
    still = base.model_copy(update={"contact": base.contact.model_copy(update={"friction_coefficient": 0.0})})
    frictionless = run_model(SceneFrames.from_scene(still), "exact", [0])
    assert np.allclose(ramp.values, frictionless.values, rtol=0, atol=1e-9 * np.abs(frictionless.values).max())


def test_fingerprint_ridges_enter_the_gap():
    flat = SinusoidalGrating(period_m=2e-3, amplitude_m=0.05e-6)
    scene = _finger(flat, model="exact", fingerprint_period_m=0.5e-3, fingerprint_height_m=5e-6)
    frames = SceneFrames.from_scene(scene)
    ridges = frames.ridges()
    assert set(np.unique(ridges)) == {0.0, 5e-6}
    assert np.allclose(frames.gap(0) + frames.heights(0) + ridges,
                       (frames.x[None, :] ** 2 + frames.y[:, None] ** 2) / 0.02)


def test_refusals():
    ridged = _finger(SinusoidalGrating(period_m=2e-3, amplitude_m=1e-6), fingerprint_period_m=0.5e-3)
    with pytest.raises(ValueError, match="fingerprint_height: the 'auto' model"):
        scene_signals(ridged)
    cell = _cell(0.5)
    bumpy = cell.model_copy(update={"surface": IsolatedDefect(shape="bump", size_m=0.4e-3, height_m=2e-6)})
    with pytest.raises(ValueError, match="a periodic cell needs a periodic surface"):
        scene_signals(bumpy)
    with pytest.raises(ValueError, match="model: must be one of"):
        scene_signals(cell, "best")
    frames = SceneFrames.from_scene(cell)
    with pytest.raises(ValueError, match="model: must be 'exact'"):
        run_model(frames, "auto")
    with pytest.raises(ValueError, match="model: tractions"):
        frames.tractions("exact", 0)
    with pytest.raises(ValueError, match="approx: shape"):
        signal_error(np.zeros((2, 1, 1)), np.zeros((3, 1, 1)))


@pytest.mark.parametrize("fields, match", [
    (dict(mean_pressure_pa=1e3, normal_force_n=1.0), "makes a periodic cell without a finger"),
    (dict(normal_force_n=1.0), "finger_radius missing"),
    (dict(mean_pressure_pa=1e3, fingerprint_height_m=1e-5), "needs fingerprint_period"),
    (dict(mean_pressure_pa=1e3, tol=0.0), "tol"),
    (dict(mean_pressure_pa=1e3, model="best"), "model"),
    (dict(mean_pressure_pa=-1.0), "mean_pressure"),
])
def test_contact_record_refusals(fields, match):
    with pytest.raises(ValueError, match=match):
        Contact(**fields)


def test_scan_onset_refuses_a_negative_ramp():
    with pytest.raises(ValueError, match="onset"):
        Scan(speed_m_per_s=0.01, duration_s=0.01, sampling_rate_hz=100, onset_s=-1.0)


def _rough_cell(mean_pressure, model="auto"):
    from tactilab.data_schemas.lab_surfaces import RandomRoughSurface

    plate = RandomRoughSurface(rms_height_m=0.2e-6, hurst=0.8, seed=2, spacing_m=20e-6, size_m=(0.64e-3, 0.64e-3))
    return Scene(material=SkinMaterial(young_modulus_pa=E, poisson_ratio=NU), surface=plate,
                 contact=Contact(mean_pressure_pa=mean_pressure, friction_coefficient=MU, model=model),
                 sensors=SensorArray.grid(2, 2, 0.2e-3, 0.2e-3, quantity="strain", components=("zz", "zx")),
                 scan=Scan(speed_m_per_s=0.02, duration_s=0.004, sampling_rate_hz=1000))


def test_a_random_rough_cell_in_full_contact_is_the_linear_model_and_auto_picks_it():
    frames = SceneFrames.from_scene(_rough_cell(1e3))
    p_star = max(-frames.texture_pressure(0).min(), 1.0)
    scene = _rough_cell(2 * p_star)
    values, info = scene_signals(scene)
    exact, _ = scene_signals(scene, "exact")
    assert frames.shape == (32, 32) and info["model"] == "linear", info["reason"]
    assert signal_error(values, exact) <= 1e-8
    assert "periodic-cell estimate (interface_model_errors)" in info["reason"]


def test_a_random_rough_cell_in_partial_contact_needs_the_exact_model():
    frames = SceneFrames.from_scene(_rough_cell(1e3))
    p_star = -frames.texture_pressure(0).min()
    values, info = scene_signals(_rough_cell(0.2 * p_star))
    assert info["model"] == "exact" and min(info["errors"].values()) > 1e-2


def test_a_cell_has_no_finger_and_a_display_scene_no_interface():
    from tactilab.forward import BiomimeticFinger

    with pytest.raises(ValueError, match="a periodic cell \\(mean_pressure\\) has no finger"):
        BiomimeticFinger.from_scene(_cell(0.5))
    with pytest.raises(ValueError, match="the interface models need a finger or a periodic cell"):
        SceneFrames.from_scene(_cell(0.5).model_construct(**{**dict(_cell(0.5)), "contact": None}))


def _punch_error(n):
    """The scene's signal on a deep square grating (plateaus never leave the skin's reach, grooves never
    touched) against the periodic flat punch's closed-form harmonics at depth, n nodes per period."""
    from tactilab.data_schemas.surface import SquareWaveGrating
    from tactilab.forward import PeriodicFlatPunch, harmonic_field

    h, width = L / n, L / 2
    scene = Scene(material=SkinMaterial(young_modulus_pa=E, poisson_ratio=NU),
                  surface=SquareWaveGrating(element_width_m=width, amplitude_m=20e-6, start_m=h / 2),
                  contact=Contact(mean_pressure_pa=1e3, model="exact"), sensors=SENSORS,
                  scan=Scan(speed_m_per_s=3 * h * 1000, duration_s=0.003, sampling_rate_hz=1000))
    values, _ = scene_signals(scene, grid_spacing=h)
    harmonics = PeriodicFlatPunch(width / 2, L, 1e3).harmonics(2000)  # the plateau's cells span its width
    want = np.array([harmonic_field(harmonics, L, SENSORS.positions_m[:, 0] - (h / 2 + width / 2 - u),
                                    SENSORS.depth_m, E, NU, components=SENSORS.components).T
                     for u in scene.scan.positions_m])
    return float(np.abs(values - want).max() / np.abs(want).max())


def test_a_deep_square_grating_cell_reads_the_periodic_flat_punch():
    """Plateau pressures with inverse-square-root edges: the error falls like the spacing (measured
    1.3e-2, 6.8e-3 and 3.3e-3 of the signal at 128, 256 and 512 nodes per period)."""
    coarse, fine = _punch_error(128), _punch_error(256)
    assert fine <= 1e-2 and fine <= 0.6 * coarse


def _small_rough_cell(ratio, model="exact", size=(0.32e-3, 0.32e-3)):
    """A 16 x 16-node random_rough plate as a periodic cell at ``ratio`` times its full-contact pressure."""
    from tactilab.data_schemas.lab_surfaces import RandomRoughSurface

    plate = RandomRoughSurface(rms_height_m=0.2e-6, hurst=0.8, seed=5, spacing_m=20e-6, size_m=size)
    probe = _rough_cell(1e3).model_copy(update={"surface": plate})
    p_star = float(-SceneFrames.from_scene(probe, grid_spacing=10e-6).texture_pressure(0).min())
    sensors = SensorArray(positions_m=[[0.0, 0.0], [0.1e-3, -0.06e-3]], depth_m=0.15e-3, quantity="strain",
                          components=("zz", "zx", "yz"))
    return Scene(material=SkinMaterial(young_modulus_pa=E, poisson_ratio=NU), surface=plate,
                 contact=Contact(mean_pressure_pa=ratio * p_star, friction_coefficient=MU, model=model),
                 sensors=sensors, scan=Scan(speed_m_per_s=0.04, duration_s=0.003, sampling_rate_hz=1000,
                                            start_position_m=-0.1e-3))


@pytest.mark.filterwarnings("ignore::tactilab.forward.AccuracyWarning")  # 16 nodes: small patches, on purpose
def test_a_random_rough_cell_equals_solve_contact_on_the_plates_period_and_auto_runs_it():
    """Each frame of the cell against its own periodic solve_contact (cold, the plate's heights at the
    plate's nodes moved by the scan) read by an independent field solve (HalfSpace.strain)."""
    from tactilab.forward import SurfaceLoad

    scene = _small_rough_cell(0.3)
    values, info = scene_signals(scene)
    frames = info["frames"]
    assert frames.shape == (16, 16) and frames.spacing == (20e-6, 20e-6)
    plate, skin = scene.surface, HalfSpace(E, NU)
    ny, nx = frames.shape
    X, Y = np.meshgrid((np.arange(nx) - nx // 2) * 20e-6, (np.arange(ny) - ny // 2) * 20e-6)
    want = []
    for u in scene.scan.positions_m:
        sol = solve_contact(skin, -plate.height_at(X + u, Y), 20e-6, periodic=True,
                            mean_pressure=scene.contact.mean_pressure_pa, friction=MU, condition="sliding",
                            slide_direction=(1.0, 0.0), tol=1e-10)
        assert 0.05 < sol.contact_fraction < 0.95  # partial contact: neither cheap model is exact here
        load = SurfaceLoad(p=sol.pressure, qx=sol.qx, qy=sol.qy, spacing=20e-6, periodic=True)
        field = skin.strain(load, [scene.sensors.depth_m], points=scene.sensors.positions_m[:, :2],
                            components=scene.sensors.components)
        want.append(field.data["strain"].values.reshape(3, 2).T)
    err = signal_error(values, np.array(want))
    assert err <= 1e-4, err
    auto, chosen = scene_signals(scene.model_copy(update={"contact": scene.contact.model_copy(
        update={"model": "auto"})}))
    assert chosen["model"] == "exact" and np.array_equal(auto, values), chosen["reason"]
    assert min(chosen["errors"].values()) > 1e-2  # the cheap models miss tol in partial contact


@pytest.mark.parametrize("size, spacing, match", [
    ((0.30e-3, 0.32e-3), None, r"grid_spacing: a random_rough periodic cell .* 2e-05 m \(the plate spacing_m\) "
                               r"gives 15 nodes along x; give a grid_spacing that does, e.g\. 1e-05 m"),
    ((0.32e-3, 0.32e-3), 30e-6, r"grid_spacing: .* 3e-05 m gives 10\.6667 nodes along x; .* e\.g\. 2e-05 m"),
    ((0.32e-3, 0.32e-3), 80e-6, r"grid_spacing: .* 8e-05 m gives 4 nodes along x"),
])
def test_a_random_rough_cell_grid_must_tile_the_plates_period(size, spacing, match):
    from tactilab.data_schemas.lab_surfaces import RandomRoughSurface

    plate = RandomRoughSurface(rms_height_m=0.2e-6, seed=5, spacing_m=20e-6, size_m=size)
    scene = _small_rough_cell(0.3).model_copy(update={"surface": plate})
    with pytest.raises(ValueError, match=match):
        SceneFrames.from_scene(scene, grid_spacing=spacing)
    fine = SceneFrames.from_scene(scene, grid_spacing=10e-6)  # half the plate's spacing always tiles it
    assert fine.shape == tuple(int(round(v / 10e-6)) for v in size[::-1])


def _rough_scan_spectra(ratio):
    """The sensor's spectrum (sigma_zz at 0.2 mm, two sensors) over one period of a random rough cell scanned
    one node per frame with the exact model, and the linear theory's spectrum computed from the plate's own
    Fourier coefficients: p = p_bar + E* |k| H~ / 2 times the half-space's zz transfer -(1 + |k| z) e^(-|k| z)."""
    from tactilab.data_schemas.lab_surfaces import RandomRoughSurface

    plate = RandomRoughSurface(rms_height_m=0.2e-6, hurst=0.8, seed=2, spacing_m=20e-6, size_m=(0.64e-3, 0.64e-3))
    ny, nx = plate.heights_m.shape
    kx, ky = np.meshgrid(2 * np.pi * np.fft.fftfreq(nx, 20e-6), 2 * np.pi * np.fft.fftfreq(ny, 20e-6))
    k = np.hypot(kx, ky)
    texture = E_STAR * k * np.fft.fft2(plate.heights_m) / plate.heights_m.size / 2
    tension = float(np.abs(texture).sum())  # a bound on the largest tension of the texture's pressure
    z, p_bar = 0.2e-3, ratio * tension
    sensors = SensorArray(positions_m=[[0.0, 0.0], [0.1e-3, 0.2e-3]], depth_m=z, quantity="stress", components=("zz",))
    scene = Scene(material=SkinMaterial(young_modulus_pa=E, poisson_ratio=NU), surface=plate,
                  contact=Contact(mean_pressure_pa=p_bar, model="exact"), sensors=sensors,
                  scan=Scan(speed_m_per_s=0.02, duration_s=nx * 1e-3, sampling_rate_hz=1000))  # one node per frame
    values, _ = scene_signals(scene)
    pressure = texture.copy()
    pressure[0, 0] = p_bar
    transfer = -(1 + k * z) * np.exp(-k * z) * pressure
    theory = np.array([[(transfer * np.exp(1j * (kx * (xs + u) + ky * ys))).sum().real
                        for xs, ys in sensors.positions_m[:, :2]] for u in scene.scan.positions_m])
    spectrum = lambda s: np.abs(np.fft.rfft(s - s.mean(axis=0), axis=0)) ** 2  # noqa: E731
    return spectrum(values[:, :, 0]), spectrum(theory)


def test_a_random_rough_scans_spectrum_has_the_linear_theorys_shape_where_it_is_valid():
    """Full contact (p_bar above the texture's largest tension): the exact model's sensor spectrum is the
    linear theory's, bin by bin over twelve decades of power; in partial contact it is not (the oracle
    can fail)."""
    exact, theory = _rough_scan_spectra(2.0)
    kept = theory >= 1e-12 * theory.max()
    assert kept.sum() >= 12 and np.abs(exact[kept] / theory[kept] - 1).max() <= 1e-6
    exact, theory = _rough_scan_spectra(0.03)  # 3 % of the tension bound: the valleys leave the skin
    kept = theory >= 1e-9 * theory.max()
    assert np.abs(exact[kept] / theory[kept] - 1).max() > 0.1
