"""Display interface, travelling-wave drive and the simulated display (docs/theory.md 4a)."""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.devices.display import Display, DisplayError, render_drive, virtual_height
from tactilab.experiments.devices.display_limits import check_frames, limit_violations, limits, resolve_command
from tactilab.experiments.devices.display_strain import (
    row_strain,
    sliding_surface_strain_amplitude,
    strain_gain_line_load,
)
from tactilab.experiments.devices.simulated_display import SimulatedDisplay

STIM = dict(amplitude_m=10e-6, pitch_m=2.0e-3, speed_m_per_s=0.04, duration_s=0.2, frame_rate_hz=1000.0)


def phi_psi(x, d, z):
    """Phi and Psi of docs/theory.md 4a, transcribed literally (the pair -q at -d, +q at +d)."""
    a, b = x + d, x - d
    phi = 0.5 * (a / (z**2 + a**2) - b / (z**2 + b**2)) - z**2 * (a / (z**2 + a**2) ** 2 - b / (z**2 + b**2) ** 2)
    psi = z * ((z**2 - b**2) / (z**2 + b**2) ** 2 - (z**2 - a**2) / (z**2 + a**2) ** 2) - (
        z / (z**2 + b**2) - z / (z**2 + a**2))
    return phi, psi


def test_pair_of_line_tractors_matches_phi_psi_closed_form():
    """Superposed single-tractor kernels reproduce the pair formulas Phi, Psi of docs/theory.md 4a."""
    d, z, e, q = 0.6e-3, 1.0e-3, 2.0e5, 3.0
    x = np.linspace(-6e-3, 6e-3, 241)
    eps_xx, eps_xz = row_strain(x, [-d, d], np.array([-q, q]), z, e)
    phi, psi = phi_psi(x, d, z)
    scale = 3 * q / (math.pi * e)
    np.testing.assert_allclose(eps_xx, scale * phi, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(2 * eps_xz, scale * psi, rtol=1e-12, atol=1e-18)  # gamma = 2 eps


def flamant_strain(x, z, e, t):
    """Flamant tangential line load (docs/theory.md 3) + plane-strain Hooke with nu = 1/2."""
    r4 = (x**2 + z**2) ** 2
    sxx, szz, sxz = -2 * t * x**3 / (math.pi * r4), -2 * t * x * z**2 / (math.pi * r4), -2 * t * x**2 * z / (math.pi * r4)
    nu = 0.5
    tr = sxx + nu * (sxx + szz) + szz
    return ((1 + nu) * sxx - nu * tr) / e, (1 + nu) * sxz / e


def test_single_tractor_matches_flamant_stress_and_hooke():
    z, e, t = 0.8e-3, 1.5e5, 2.0
    x = np.linspace(-4e-3, 4e-3, 81)
    exx, exz = flamant_strain(x, z, e, t)
    eps_xx, eps_xz = row_strain(x, [0.0], np.array([t]), z, e)
    np.testing.assert_allclose(eps_xx, exx, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(eps_xz, exz, rtol=1e-12, atol=1e-18)


def test_tractor_of_finite_width_matches_quadrature_of_line_loads():
    """A strip of width c is the average of line loads over [-c/2, c/2] (Gauss-Legendre)."""
    z, e, t, c = 0.5e-3, 2e5, 1.0, 0.6e-3
    x = np.linspace(-3e-3, 3e-3, 61)
    nodes, weights = np.polynomial.legendre.leggauss(40)
    exx = sum(w / 2 * flamant_strain(x - s * c / 2, z, e, t)[0] for s, w in zip(nodes, weights))
    exz = sum(w / 2 * flamant_strain(x - s * c / 2, z, e, t)[1] for s, w in zip(nodes, weights))
    eps_xx, eps_xz = row_strain(x, [0.0], np.array([t]), z, e, footprint_m=c)
    np.testing.assert_allclose(eps_xx, exx, rtol=1e-8, atol=1e-12 * np.abs(exx).max())
    np.testing.assert_allclose(eps_xz, exz, rtol=1e-8, atol=1e-12 * np.abs(exz).max())


def test_rms_gain_agrees_with_the_optimal_spacing_design():
    """At the optimal half spacing d (p = 4 d), the forward model's matching line load
    (docs/theory.md 4a, peak-shear match with the sqrt(2) RMS factor) and this RMS-strain gain
    are two definitions of "the same strain"; they agree to within 10 % at Z = 1 mm."""
    from tactilab.forward.synthesis import matching_line_load, optimal_half_spacing

    design = optimal_half_spacing(1.0e-3)
    d = design.d
    gain = strain_gain_line_load(np.arange(-4.5, 5) * 2 * d, 2 * d, pitch_m=4 * d, depth_m=1.0e-3,
                                 young_modulus_pa=1e6)
    assert gain == pytest.approx(matching_line_load(1.0, None, None, 1e6, design), rel=0.1)


def test_drive_follows_virtual_surface_at_each_tractor():
    desc = DisplayDescription.stress2()
    frames = render_drive(desc, **STIM, ramp_s=0.0, gain=2.0, phase_rad=0.3)
    t = np.arange(frames.shape[0]) / STIM["frame_rate_hz"]
    expected = 2.0 * virtual_height(desc.tractor_x_m[None, :] + STIM["speed_m_per_s"] * t[:, None],
                                    surface="sinusoid", amplitude_m=STIM["amplitude_m"],
                                    pitch_m=STIM["pitch_m"], phase_rad=0.3)
    assert frames.shape == (200, desc.n_tractors)
    for row in range(desc.rows):  # row-major: every row gets the same drive
        np.testing.assert_allclose(frames[:, row * desc.columns:(row + 1) * desc.columns], expected, rtol=1e-12)
    # A travelling wave: tractor n+1 leads tractor n by pitch_x / V seconds.
    lag = int(round(desc.pitch_x_m / STIM["speed_m_per_s"] * STIM["frame_rate_hz"]))
    np.testing.assert_allclose(frames[lag:, 0], frames[:-lag, 1], rtol=1e-9, atol=1e-12)


def test_drive_ramps_from_and_back_to_rest_and_square_surface():
    desc = DisplayDescription.braille_row()
    frames = render_drive(desc, **STIM, surface="square", ramp_s=0.02, gain=1.0)
    assert np.all(frames[0] == 0) and np.all(frames[-1] == 0)
    middle = frames[40:160]
    assert set(np.unique(np.abs(middle[middle != 0]))) == {STIM["amplitude_m"]}


def test_default_gain_matches_sliding_surface_rms_strain():
    """Simulated strain (time average over one scan period) has the sliding surface's RMS."""
    desc = DisplayDescription.braille_row(n_tractors=16)
    z, e = 1.0e-3, 3.0e5
    period_s = STIM["pitch_m"] / STIM["speed_m_per_s"]
    stim = {**STIM, "duration_s": 4 * period_s}
    frames = render_drive(desc, **stim, ramp_s=0.0, depth_m=z, young_modulus_pa=e)
    sim = SimulatedDisplay(desc, depth_m=z, young_modulus_pa=e,
                           x_m=np.linspace(desc.tractor_x_m[0] - 0.6e-3, desc.tractor_x_m[-1] + 0.6e-3, 1501))
    eps_xx, eps_xz = sim.strain(frames[: int(round(period_s * 1000))])
    rms2 = np.mean(2 * eps_xx**2 + 2 * eps_xz**2)
    c = sliding_surface_strain_amplitude(STIM["amplitude_m"], STIM["pitch_m"], z)
    assert rms2 == pytest.approx(2 * c * c, rel=2e-2)
    # The traction gain is proportional to E and the line load is traction * width.
    g = strain_gain_line_load(desc.tractor_x_m, desc.pitch_x_m, pitch_m=STIM["pitch_m"], depth_m=z,
                              young_modulus_pa=2 * e, footprint_m=desc.tractor_width_m)
    assert np.max(np.abs(frames)) * 2 * desc.tractor_width_m == pytest.approx(
        g * STIM["amplitude_m"], rel=1e-2)


def test_deflection_command_gain_is_one_to_one():
    desc = DisplayDescription.braille_row(max_traction_pa=None)
    assert resolve_command(desc) == "deflection"
    frames = render_drive(desc, **STIM, ramp_s=0.0)
    np.testing.assert_allclose(frames, render_drive(desc, **STIM, ramp_s=0.0, gain=1.0), rtol=0)


@pytest.mark.parametrize("change,match", [
    ({"amplitude_m": -1e-6}, "amplitude_m: must be a finite number >= 0"),
    ({"pitch_m": 0.0}, "pitch_m: must be finite and > 0 m, got 0.0"),
    ({"speed_m_per_s": math.inf}, "speed_m_per_s: must be finite"),
    ({"duration_s": math.nan}, "duration_s: must be finite and > 0 s, got nan"),
    ({"frame_rate_hz": -5.0}, "frame_rate_hz: must be finite and > 0 Hz, got -5.0"),
    ({"ramp_s": 0.15}, r"ramp_s: must lie in \[0, duration_s / 2\]"),
    ({"phase_rad": math.nan}, "phase_rad: must be finite"),
    ({"depth_m": 0.0}, "depth_m: every depth must be finite and > 0 m"),
    ({"young_modulus_pa": True}, "young_modulus_pa: Young's modulus must be finite and > 0 Pa, got True"),
    ({"gain": math.nan}, "gain: must be finite"),
    ({"surface": "triangle"}, "surface: must be 'sinusoid' or 'square'"),
    ({"command": "force"}, "command: must be 'traction' or 'deflection'"),
])
def test_render_drive_rejects_bad_parameters(change, match):
    with pytest.raises(ValueError, match=match):
        render_drive(DisplayDescription.braille_row(), **{**STIM, **change})


def test_command_without_a_limit_is_rejected():
    with pytest.raises(ValueError, match="max_deflection_m"):
        resolve_command(DisplayDescription.braille_row(max_deflection_m=None), "deflection")


@pytest.mark.parametrize("frames,rate,match", [
    (np.zeros((5, 3)), 1000.0, r"frames: must have shape \(n_frames >= 1, n_tractors = 10\)"),
    (np.zeros((0, 10)), 1000.0, r"got shape \(0, 10\)"),
    (np.full((4, 10), np.nan), 1000.0, "frames: must be finite, got nan at frame 0, tractor 0"),
    (np.zeros((4, 10)), 0.0, "frame_rate_hz: must be finite and > 0 Hz, got 0.0; give e.g. 1000.0"),
    (np.zeros((4, 10)), True, "frame_rate_hz: must be finite and > 0 Hz, got True"),
    (np.zeros((4, 10)), 2000.0, "frame_rate_hz: 2000.0 Hz exceeds the refresh rate of display "
                                "'VirtualBrailleRow', 1000.0 Hz"),
])
def test_check_frames_rejects(frames, rate, match):
    with pytest.raises(ValueError, match=match):
        check_frames(frames, rate, DisplayDescription.braille_row())


def test_limit_violations_finds_each_kind():
    desc = DisplayDescription.braille_row(max_duty_cycle=0.5, max_slew_rate_per_s=100.0)
    lim = limits(desc)
    assert lim["step"][0] == pytest.approx(0.1 * desc.max_traction_pa)
    frames = np.zeros((10, 10))
    frames[1:9, 0] = 0.5 * lim["step"][0]  # within amplitude and slew, but on in 8 of 10 frames
    frames[3, 1] = 1.5 * lim["amplitude"][1]
    kinds = {(v["kind"], v["tractor"]) for v in limit_violations(frames, 1000.0, desc)}
    assert ("amplitude", 1) in kinds and ("slew", 1) in kinds and ("duty", 0) in kinds
    assert limit_violations(np.zeros((10, 10)), 1000.0, desc) == []


class _Recorder(Display):
    def __init__(self, description):
        super().__init__(description)
        self.zeroed = 0

    def _play(self, frames, rate):
        from tactilab.experiments.devices.display import PlaybackReport
        return PlaybackReport(frames_sent=len(frames), late=0, missing=0, acked=len(frames))

    def _zero(self):
        self.zeroed += 1


def test_bare_display_refuses_frames_beyond_limits_and_play_before_load():
    desc = DisplayDescription.braille_row()
    display = _Recorder(desc)
    with pytest.raises(DisplayError, match="play: no frames loaded"):
        display.play()
    frames = np.zeros((3, 10))
    frames[1, 4] = 2 * desc.max_traction_pa
    with pytest.raises(ValueError, match="break the limits of display 'VirtualBrailleRow'.*SafeDisplay"):
        display.load(frames, 1000.0)
    display.load(np.zeros((3, 10)), 1000.0)
    assert display.play().frames_sent == 3 and not display.frames.flags.writeable


def test_simulated_display_plays_records_and_zeroes():
    desc = DisplayDescription.stress2()
    sim = SimulatedDisplay(desc)
    frames = np.clip(render_drive(desc, **STIM), -desc.max_traction_pa / 2, desc.max_traction_pa / 2)
    sim.load(frames, 1000.0)
    report = sim.play()
    assert (report.frames_sent, report.acked, report.missing, report.stopped) == (200, 200, 0, False)
    np.testing.assert_array_equal(sim.played, frames)
    eps_xx, eps_xz = sim.strain()
    assert eps_xx.shape == (200, desc.rows, sim.x_m.size) == eps_xz.shape
    np.testing.assert_allclose(eps_xx[:, 0], eps_xx[:, 5])  # rows share the drive
    sim.outputs[:] = 1.0
    sim.zero()
    assert not sim.outputs.any() and len(sim.zero_times) == 1


def test_simulated_display_realtime_and_stop_from_another_thread():
    desc = DisplayDescription.braille_row()
    sim = SimulatedDisplay(desc, realtime=True)
    sim.load(np.zeros((400, 10)), 1000.0)
    timer = threading.Timer(0.05, sim.stop)
    timer.start()
    report = sim.play()
    timer.join()
    assert report.stopped and 0 < report.frames_sent < 400
    assert report.send_intervals_s.shape == (report.frames_sent - 1,)
    sim.load(np.zeros((20, 10)), 1000.0)
    report = sim.play()  # a new play clears the stop request
    assert report.frames_sent == 20 and not report.stopped and report.duration_s > 0


def test_simulated_display_deflection_needs_stiffness():
    desc = DisplayDescription.braille_row(max_traction_pa=None)
    with pytest.raises(ValueError, match="tractor_stiffness_pa_per_m: required"):
        SimulatedDisplay(desc)
    sim = SimulatedDisplay(desc, tractor_stiffness_pa_per_m=1e9)
    loads = sim.line_loads(np.full((1, 10), 1e-6))
    np.testing.assert_allclose(loads, 1e-6 * 1e9 * desc.tractor_width_m)


@pytest.mark.parametrize("kwargs,match", [
    ({"depth_m": -1.0}, "depth_m: every depth must be finite and > 0 m"),
    ({"young_modulus_pa": math.nan}, "young_modulus_pa: Young's modulus must be finite and > 0 Pa, got nan"),
    ({"tractor_stiffness_pa_per_m": 0.0}, "tractor_stiffness_pa_per_m: must be finite and > 0 Pa/m, got 0.0"),
    ({"x_m": [[0.0]]}, "x_m: must be a non-empty 1-D array"),
    ({"x_m": [np.nan]}, "x_m: must be a non-empty 1-D array"),
])
def test_simulated_display_rejects_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SimulatedDisplay(DisplayDescription.braille_row(), **kwargs)


def test_with_block_zeroes_and_closes():
    closed = []

    class Closing(_Recorder):
        def close(self):
            closed.append(True)

    with Closing(DisplayDescription.braille_row()) as display:
        display.load(np.zeros((2, 10)), 1000.0)
        display.play()
    assert display.zeroed == 1 and closed == [True]


def test_3d_patches_of_long_tractors_approach_the_plane_model():
    """Two independent models: Cerruti patches integrated in 3-D (forward.tractor_display) and
    the plane-strain strip closed form agree under long tractors (40 mm >> Z = 0.5 mm)."""
    desc = DisplayDescription.braille_row(n_tractors=4, tractor_length_m=40e-3)
    sim = SimulatedDisplay(desc, depth_m=0.5e-3, young_modulus_pa=2e5)
    frames = np.array([[1e3, -2e3, 5e2, 3e3]])
    voigt = sim.strain_3d(frames)
    eps_xx, eps_xz = sim.strain(frames)
    assert voigt.shape == (1, sim.x_m.size, 6)
    np.testing.assert_allclose(voigt[0, :, 0], eps_xx[0, 0], atol=0.01 * np.abs(eps_xx).max())
    np.testing.assert_allclose(voigt[0, :, 4], eps_xz[0, 0], atol=1e-3 * np.abs(eps_xz).max())
    np.testing.assert_allclose(voigt[0, :, 2], -eps_xx[0, 0], atol=0.02 * np.abs(eps_xx).max())  # nu = 1/2


@pytest.mark.parametrize("change,match", [
    ({"x_m": np.array([0.0, np.nan])}, "x_m: positions must be finite"),
    ({"amplitude_m": math.nan}, "amplitude_m: must be a finite number in m, got nan"),
    ({"pitch_m": math.inf}, "pitch_m: must be finite and > 0 m, got inf"),
    ({"phase_rad": math.nan}, "phase_rad: must be a finite number in rad, got nan"),
])
def test_virtual_height_rejects_non_finite_values(change, match):
    """These used to come back as NaN heights."""
    kwargs = {"x_m": np.array([0.0, 1e-3]), "surface": "sinusoid", "amplitude_m": 1e-5, "pitch_m": 2e-3,
              "phase_rad": 0.0}
    assert np.all(np.isfinite(virtual_height(**kwargs)))
    with pytest.raises(ValueError, match=match):
        virtual_height(**{**kwargs, **change})


@pytest.mark.parametrize("args,match", [
    ((math.nan, 2e-3, 1e-3), "amplitude_m: must be a finite number in m, got nan"),
    ((1e-5, 0.0, 1e-3), "pitch_m: must be finite and > 0 m, got 0.0"),
    ((1e-5, 2e-3, math.nan), "depth_m: every depth must be finite and > 0 m .*, got nan"),
])
def test_sliding_surface_strain_amplitude_rejects_bad_values(args, match):
    with pytest.raises(ValueError, match=match):
        sliding_surface_strain_amplitude(*args)


def test_steady_drive_is_the_limited_drive_between_the_ramps_and_models_read_its_strain():
    """``steady_drive`` renders and limits as the safety layer does and drops the ramps; the
    strain at another depth equals the Flamant rows at that depth; a transduction model of the
    display's strain reads exactly those rows (the one route shared with the simulated observer)."""
    from tactilab.data_schemas.experiment import Stimulus
    from tactilab.experiments import TransductionModel
    from tactilab.experiments.devices import limit_drive

    display = SimulatedDisplay(DisplayDescription.braille_row())
    stimulus = Stimulus(amplitude_m=40e-6, pitch_m=2e-3, speed_m_per_s=0.04, duration_s=0.2, ramp_s=0.02)
    frames = render_drive(display.description, **stimulus.model_dump(), depth_m=display.depth_m,
                          young_modulus_pa=display.young_modulus_pa)
    applied, events = limit_drive(frames, stimulus.frame_rate_hz, display.description, display.command)
    assert events  # 40 um asks for more traction than the display gives: the limiter acts
    steady = display.steady_drive(stimulus)
    assert steady.shape == (len(frames) - 40, display.description.n_tractors)  # 20 ramp frames at each end
    np.testing.assert_array_equal(steady, applied[20:-20])
    assert not limit_violations(steady, stimulus.frame_rate_hz, display.description)
    q = display.line_loads(steady)
    for depth in (0.5e-3, 2e-3):
        exx, exz = row_strain(display.x_m, display.description.tractor_x_m, q, depth, display.young_modulus_pa,
                              display.description.tractor_width_m)
        got = display.strain(steady, depth_m=depth)
        np.testing.assert_array_equal(got[0], exx)
        np.testing.assert_array_equal(got[1], exz)
    np.testing.assert_array_equal(display.strain(steady)[0], display.strain(steady, depth_m=display.depth_m)[0])
    exx, exz = display.strain(steady, depth_m=2e-3)
    model = TransductionModel("xx@2mm", statistic="rms", source="display", display=display)
    assert model.statistic_of(stimulus) == pytest.approx(float(np.sqrt(np.mean(exx * exx))), rel=1e-12)
    with pytest.raises(ValueError, match="depth_m: every depth must be finite and > 0 m .*, got -0.001"):
        display.strain(steady, depth_m=-1e-3)
