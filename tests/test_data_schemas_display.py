"""DisplayDescription: geometry, presets, JSON round-trip, every validation rule, command limits."""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.data_schemas.display import DisplayDescription


def test_stress2_geometry_is_a_centred_6_by_10_grid():
    d = DisplayDescription.stress2()
    assert d.shape == (6, 10) and d.n_tractors == 60
    pos = d.tractor_positions_m
    assert pos.shape == (60, 2)
    # centred on the origin, spacing equal to the pitch, row-major (x varies fastest)
    np.testing.assert_allclose(pos.mean(axis=0), [0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(np.diff(pos[:10, 0]), 1.2e-3, rtol=1e-12)
    np.testing.assert_allclose(pos[10, 1] - pos[0, 1], 1.4e-3, rtol=1e-12)
    assert d.half_spacing_m == pytest.approx(0.6e-3)
    assert d.frame_period_s == pytest.approx(1e-3)


def test_braille_row_is_one_row_without_row_pitch():
    b = DisplayDescription.braille_row(n_tractors=8, pitch_x_m=1.0e-3, center_m=(2e-3, 1e-3))
    assert b.rows == 1 and b.pitch_y_m is None
    np.testing.assert_allclose(b.tractor_y_m, [1e-3])
    np.testing.assert_allclose(b.tractor_x_m, 2e-3 + (np.arange(8) - 3.5) * 1e-3)


@pytest.mark.parametrize("make", [DisplayDescription.stress2, DisplayDescription.braille_row])
def test_json_round_trip_is_exact(make, tmp_path):
    d = make()
    assert DisplayDescription.from_json(d.to_json()) == d
    assert DisplayDescription.load(d.save(tmp_path / "d.json")) == d


def test_records_are_frozen():
    d = DisplayDescription.stress2()
    with pytest.raises(ValueError, match="frozen"):
        d.rows = 3


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        (dict(rows=0), r"rows must be >= 1 .*got 0"),
        (dict(columns=-2), r"columns must be >= 1 .*got -2"),
        (dict(pitch_x_m=0.0), r"pitch_x_m must be > 0, got 0.0; give a positive number in m"),
        (dict(pitch_y_m=-1e-3), r"pitch_y_m must be > 0, got -0.001"),
        (dict(pitch_x_m=float("nan")), r"pitch_x_m must be finite, got nan"),
        (dict(tractor_width_m=float("inf")), r"tractor_width_m must be finite, got inf"),
        (dict(max_traction_pa=-5.0), r"max_traction_pa must be > 0 \(a traction limit\), got -5.0"),
        (dict(max_deflection_m=0.0), r"max_deflection_m must be > 0 \(a deflection limit\)"),
        (dict(max_slew_rate_per_s=0.0), r"max_slew_rate_per_s must be > 0"),
        (dict(max_duty_cycle=0.0), r"max_duty_cycle must lie in \(0, 1\] .*got 0.0"),
        (dict(max_duty_cycle=1.5), r"max_duty_cycle must lie in \(0, 1\] .*got 1.5"),
        (dict(frame_rate_hz=-1.0), r"frame_rate_hz must be > 0 .*give a positive number in Hz"),
        (dict(center_m=(0.0, float("nan"))), r"center_m.*must be finite"),
        (dict(display_id=""), r"display_id"),
        (dict(display_id="   "), r"display_id must not be blank"),
        (dict(max_traction_pa=None, max_deflection_m=None),
         r"max_traction_pa and max_deflection_m are both missing.*give at least one"),
        (dict(pitch_y_m=None), r"pitch_y_m is missing but rows = 6"),
        (dict(tractor_width_m=1.3e-3), r"tractor_width_m = 0.0013 exceeds pitch_x_m = 0.0012.*overlap"),
        (dict(tractor_length_m=1.5e-3), r"tractor_length_m = 0.0015 exceeds pitch_y_m = 0.0014.*overlap"),
        (dict(motion_axes="z"), r"motion_axes"),
        (dict(colour="red"), r"colour"),
    ],
)
def test_each_rule_rejects_bad_input(change, pattern):
    with pytest.raises(ValueError, match=pattern):
        DisplayDescription.stress2(**change)


def test_replace_validates_again():
    d = DisplayDescription.stress2()
    assert d.replace(rows=2).n_tractors == 20
    with pytest.raises(ValueError, match="rows must be >= 1"):
        d.replace(rows=0)


def test_check_commands_accepts_commands_within_limits():
    d = DisplayDescription.stress2()
    t = np.arange(50) / d.frame_rate_hz
    wave = 0.5 * d.max_traction_pa * np.sin(2 * np.pi * 20 * t)
    commands = np.broadcast_to(wave[:, None, None], (50, 6, 10))
    d.check_commands(commands, "traction")
    d.check_commands(commands * d.max_deflection_m / d.max_traction_pa, "deflection")


def test_check_commands_rejects_each_broken_limit():
    d = DisplayDescription.stress2()
    ok = np.zeros((4, 6, 10))
    with pytest.raises(ValueError, match=r"commands must have shape \(n_frames, 6, 10\).*got \(4, 10, 6\)"):
        d.check_commands(np.zeros((4, 10, 6)))
    with pytest.raises(ValueError, match="commands must be finite"):
        d.check_commands(np.full((4, 6, 10), np.nan))
    big = ok.copy()
    big[2, 1, 3] = 2 * d.max_traction_pa
    with pytest.raises(ValueError, match=r"exceed the traction limit .* frame 2, tractor \(row 1, column 3\)"):
        d.check_commands(big)
    jump = ok.copy()
    jump[1:, 0, 0] = d.max_traction_pa  # 0 -> full scale in one 1 ms frame: 1000 /s < 2000 /s, fine
    d.check_commands(jump)
    jump[2:, 0, 0] = -d.max_traction_pa  # full -> -full: 2 full scales in 1 ms = 2000 /s, at the limit
    d.check_commands(jump)
    slow = d.replace(max_slew_rate_per_s=500.0)
    with pytest.raises(ValueError, match=r"change too fast between frames 0 and 1 at tractor \(row 0, column 0\)"):
        slow.check_commands(jump)
    busy = d.replace(max_duty_cycle=0.5)
    on = ok.copy()
    on[:3, 2, 2] = 1.0
    with pytest.raises(ValueError, match=r"tractor \(row 2, column 2\) is driven in 0.75 of the frames"):
        busy.check_commands(on)
    with pytest.raises(ValueError, match="kind must be 'traction' or 'deflection'"):
        d.check_commands(ok, "force")
    no_deflection = d.replace(max_deflection_m=None)
    with pytest.raises(ValueError, match="has no max_deflection_m"):
        no_deflection.check_commands(ok, "deflection")


def test_check_commands_two_axis_display_uses_vector_magnitude():
    d = DisplayDescription.stress2(motion_axes="xy")
    c = np.zeros((2, 6, 10, 2))
    c[1, 0, 0] = [0.8, 0.8]  # |.| = 1.13 full scales > 1
    c *= d.max_traction_pa
    with pytest.raises(ValueError, match="exceed the traction limit"):
        d.check_commands(c)
    with pytest.raises(ValueError, match=r"or \(n_frames, rows, columns, 2\)"):
        d.check_commands(np.zeros((2, 6, 10, 3)))
    with pytest.raises(ValueError, match=r"got \(2, 6, 10, 2\)"):
        DisplayDescription.stress2().check_commands(c)
