"""Response sources: the simulated observer's forward model and decisions, and the terminal."""

from __future__ import annotations

import math
import os
import pty
import termios
import time

import numpy as np
import pytest
from scipy.special import ndtr

from tactilab.data_schemas.experiment import Protocol, Stimulus
from tactilab.experiments.procedures import PlannedLevel
from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments.session.responses import (
    SimulatedObserver, TerminalResponses, receptor_strain, rendered_strain)
from tactilab.experiments.devices.simulated_display import SimulatedDisplay
from tactilab.experiments.procedures.tasks import plan_trial


def protocol(task, **extra) -> Protocol:
    return Protocol.model_validate({
        "name": "obs", "seed": 4, "task": task, **extra,
        "stimulus": {"amplitude_m": "2um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s"},
        "procedure": {"method": "constant_stimuli", "parameter": "amplitude_m", "levels": ["1um", "2um"]}})


@pytest.mark.parametrize("amplitude,pitch,depth", [(2e-6, 2e-3, 1e-3), (20e-6, 1e-3, 0.5e-3), (5e-6, 4e-3, 3e-3)])
def test_receptor_strain_matches_the_sliding_surface_closed_form(amplitude, pitch, depth):
    """docs/theory.md 4a: eps_xx = -eps_zz = K sin, eps_xz = K cos (tensor shear), K = (2 pi/p)^2 A Z e^{-2 pi Z/p};
    the deviatoric Frobenius norm is sqrt(2) K at every point and time."""
    k = (2 * math.pi / pitch) ** 2 * amplitude * depth * math.exp(-2 * math.pi * depth / pitch)
    stimulus = Stimulus(amplitude_m=amplitude, pitch_m=pitch, speed_m_per_s=0.04)
    assert receptor_strain(stimulus, depth) == pytest.approx(math.sqrt(2) * k, rel=1e-12)
    assert receptor_strain(stimulus.model_copy(update={"amplitude_m": 0.0}), depth) == 0.0


def test_square_surface_strain_sums_its_harmonics_in_quadrature():
    """Odd harmonics 4A/(n pi) at pitch p/n are orthogonal over a period: RMS^2 = sum 2 K_n^2."""
    amplitude, pitch, depth = 3e-6, 2e-3, 0.6e-3
    total = sum(2 * ((2 * math.pi * n / pitch) ** 2 * 4 * amplitude / (n * math.pi) * depth
                     * math.exp(-2 * math.pi * n * depth / pitch)) ** 2 for n in range(1, 400, 2))
    square = Stimulus(surface="square", amplitude_m=amplitude, pitch_m=pitch, speed_m_per_s=0.04)
    assert receptor_strain(square, depth) == pytest.approx(math.sqrt(total), rel=1e-9)


@pytest.mark.parametrize("amplitude,pitch", [(1e-6, 2e-3), (3e-6, 2e-3), (1e-6, 4e-3), (1e-6, 1.2e-3)])
def test_display_strain_matches_the_virtual_surface_within_the_limits(amplitude, pitch):
    """Two independent routes: the tractor row's Flamant superposition (simulated display, after
    the safety limiter) and the sliding surface's spectral closed form agree within 1 % when the
    drive stays within the display's limits (the drive gain is defined by that match)."""
    display = SimulatedDisplay(DisplayDescription.braille_row())
    stimulus = Stimulus(amplitude_m=amplitude, pitch_m=pitch, speed_m_per_s=0.04, duration_s=0.2)
    assert rendered_strain(stimulus, display) == pytest.approx(receptor_strain(stimulus, display.depth_m), rel=0.01)


def test_an_observer_feeling_the_display_feels_the_safety_limits():
    p = protocol({"kind": "2ifc"})
    display = SimulatedDisplay(DisplayDescription.braille_row())
    felt = SimulatedObserver(p, display=display)
    ideal = SimulatedObserver(p)
    small, huge = (Stimulus(amplitude_m=a, pitch_m=2e-3, speed_m_per_s=0.04) for a in (1e-6, 40e-6))
    assert felt.drive(small) == pytest.approx(ideal.drive(small), rel=0.01)
    assert felt.drive(huge) < 0.8 * ideal.drive(huge)  # 40 um asks for more traction than 50 kPa
    assert felt.config["strain"] == "display" and ideal.config["strain"] == "surface"
    with pytest.raises(ValueError, match="display: the observer feels a display's strain only for a simulated"):
        SimulatedObserver(p, display=object())


def _proportion(observer, p, level, label, n=3000):
    hits = 0
    for i in range(n):
        plan = plan_trial(p, i, PlannedLevel(level), np.random.default_rng([9, i]))
        observer.arm(plan, 0)
        hits += observer.collect(plan).label == (plan.target if label is None else label)
    return hits / n


@pytest.mark.parametrize("kind,predicted", [
    ("yes_no", lambda d, c: ndtr(d - c)),               # P(yes | signal)
    ("2ifc", lambda d, c: ndtr(d / math.sqrt(2))),       # P(correct), test vs blank
])
def test_observer_choice_probabilities_follow_signal_detection_theory(kind, predicted):
    p = protocol({"kind": kind})
    observer = SimulatedObserver(p, threshold_strain=1e-3, criterion=1.0)
    level = 1.5e-6
    d = observer.drive(p.stimulus.with_level("amplitude_m", level))
    observed = _proportion(observer, p, level, "yes" if kind == "yes_no" else None)
    expected = predicted(d, 1.0)
    assert abs(observed - expected) < 4 * math.sqrt(expected * (1 - expected) / 3000)


def test_observer_discriminates_scanning_direction_in_2afc():
    """Templates differ by 2d in the signed feature: P(correct) = Phi(d)."""
    p = protocol({"kind": "2afc", "alternatives": {"left": {"speed_m_per_s": "-40mm/s"},
                                                   "right": {"speed_m_per_s": "40mm/s"}}})
    observer = SimulatedObserver(p, threshold_strain=2e-3)
    d = observer.drive(p.stimulus.with_level("amplitude_m", 1e-6))
    observed = _proportion(observer, p, 1e-6, None)
    assert abs(observed - ndtr(d)) < 4 * math.sqrt(ndtr(d) * (1 - ndtr(d)) / 3000)


def test_observer_same_different_and_magnitude():
    ref = {"amplitude_m": "2um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s"}
    p = protocol({"kind": "same_different"}, reference=ref)
    observer = SimulatedObserver(p, threshold_strain=1e-3)
    far = _proportion(observer, p, 20e-6, "different", n=400)
    near = _proportion(observer, p, 2.1e-6, "different", n=400)
    assert far > near
    me = protocol({"kind": "magnitude_estimation", "magnitude_min": 1, "magnitude_max": 9})
    observer = SimulatedObserver(me, threshold_strain=1e-3, magnitude_gain=1.0)
    ratings = []
    for level in (0.2e-6, 2e-6, 8e-6, 1e-3):
        plan = plan_trial(me, 0, PlannedLevel(level), np.random.default_rng(0))
        observer.arm(plan, 0)
        ratings.append(int(observer.collect(plan).label))
    assert ratings == sorted(ratings) and ratings[-1] == 9 and ratings[0] >= 1


def test_observer_is_reproducible_per_trial_and_times_responses_from_onset():
    p = protocol({"kind": "2ifc"})
    observer = SimulatedObserver(p)
    plan = plan_trial(p, 3, PlannedLevel(2e-6), np.random.default_rng([4, 3]))
    observer.arm(plan, 1_000)
    first = observer.collect(plan)
    observer.arm(plan, 5_000)
    second = observer.collect(plan)
    assert (first.label, first.rt_s) == (second.label, second.rt_s) and first.rt_s > 0.2
    assert second.monotonic_ns == 5_000 + int(second.rt_s * 1e9)


@pytest.mark.parametrize("kwargs,match", [
    ({"threshold_strain": 0.0}, "threshold_strain: must be finite and > 0, got 0.0"),
    ({"exponent": math.nan}, "exponent: must be finite and > 0, got nan"),
    ({"depth_m": -1.0}, "depth_m: every depth must be finite and > 0 m"),
    ({"criterion": math.inf}, "criterion: must be finite"),
])
def test_observer_parameters_are_validated(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SimulatedObserver(protocol({"kind": "2ifc"}), **kwargs)


# ----- terminal ----------------------------------------------------------------------------
@pytest.fixture
def terminal():
    """A pseudo-terminal: the responses read the slave side; the test types on the master."""
    master, slave = pty.openpty()
    tty_in = os.fdopen(slave, "r", closefd=False)
    tty_out = os.fdopen(os.dup(slave), "w")
    yield master, slave, tty_in, tty_out
    tty_out.close()
    tty_in.close()
    os.close(slave)
    os.close(master)


def _read_all(fd) -> str:
    import select

    out = b""
    while select.select([fd], [], [], 0.05)[0]:
        out += os.read(fd, 4096)
    return out.decode()


def test_terminal_single_keypress_without_enter_timed_from_onset(terminal):
    master, slave, tty_in, tty_out = terminal
    before = termios.tcgetattr(slave)
    p = protocol({"kind": "2ifc"})
    source = TerminalResponses(p, stdin=tty_in, stdout=tty_out)
    assert not termios.tcgetattr(slave)[3] & termios.ICANON  # no line buffering: no Enter needed
    plan = plan_trial(p, 0, PlannedLevel(2e-6), np.random.default_rng(0))
    os.write(master, b"1")  # typed BEFORE the stimulus: discarded
    time.sleep(0.1)
    onset = time.monotonic_ns()
    source.arm(plan, onset)
    os.write(master, b"x2")  # an unknown key (bell), then the answer
    response = source.collect(plan)
    assert response.label == "2" and response.monotonic_ns >= onset
    assert response.rt_s == pytest.approx((response.monotonic_ns - onset) / 1e9)
    screen = _read_all(master)
    assert "Which interval held the stimulus?" in screen and "[1] 1" in screen and "\a" in screen
    source.close()
    assert termios.tcgetattr(slave) == before  # terminal restored


def test_terminal_quit_key_interrupts(terminal):
    master, slave, tty_in, tty_out = terminal
    p = protocol({"kind": "yes_no"})
    source = TerminalResponses(p, stdin=tty_in, stdout=tty_out)
    plan = plan_trial(p, 0, PlannedLevel(2e-6), np.random.default_rng(0))
    source.arm(plan, time.monotonic_ns())
    os.write(master, b"q")
    with pytest.raises(KeyboardInterrupt, match="quit"):
        source.collect(plan)
    source.close()


def test_terminal_refuses_a_non_terminal(tmp_path):
    with open(tmp_path / "in.txt", "w+") as not_a_tty:
        with pytest.raises(OSError, match="standard input is not a terminal; .*--responses simulated"):
            TerminalResponses(protocol({"kind": "2ifc"}), stdin=not_a_tty)
