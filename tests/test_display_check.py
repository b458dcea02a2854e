"""Designs respect the display: a planned stimulus the display would limit is refused before a session.

Oracle: the safety layer itself (``limit_drive``): a stimulus is refused exactly when the
frames the runner would render for it are limited; the error names the stimulus and the limit.
"""

from __future__ import annotations

import tomllib

import pytest

from tactilab.cli.main import main
from tactilab.data_schemas import DisplayDescription, Protocol
from tactilab.experiments import SimulatedDisplay, SimulatedObserver, new_session
from tactilab.experiments.session import check_display_limits, clipped_stimuli

from test_design_multifield import PROTOCOL

LOUD = PROTOCOL.replace('amplitude_m = ["3um", "6um"]', 'amplitude_m = ["3um", "6um", "80um"]')


def test_a_design_candidate_above_the_amplitude_limit_is_refused_at_load(tmp_path, capsys):
    protocol = Protocol.model_validate(tomllib.loads(LOUD))
    braille = DisplayDescription.braille_row()
    bad = clipped_stimuli(protocol, braille)
    assert bad and all("amplitude 80 um" in where for where, _ in bad)  # only the loud candidates
    assert {hit["kind"] for _, hit in bad} == {"amplitude_clip"}
    assert clipped_stimuli(Protocol.model_validate(tomllib.loads(PROTOCOL)), braille) == []
    display = SimulatedDisplay(braille, realtime=False)
    with pytest.raises(ValueError, match=r"protocol: procedure.candidates\[[0-9]+\] .*amplitude 80 um.* exceeds "
                                         r"the display.s limits: amplitude_clip at [0-9.e+]+ Pa \(requested "
                                         r"[0-9.e+]+ Pa\)"):
        new_session(protocol, tmp_path / "s.sqlite", display, SimulatedObserver(protocol), subject="S01",
                    realtime=False)
    assert not (tmp_path / "s.sqlite").exists()  # refused before any file exists
    assert check_display_limits(protocol, braille, "allow") == len(bad)
    with pytest.raises(ValueError, match=r"clipped: must be one of \('refuse', 'allow'\), got 'drop'"):
        check_display_limits(protocol, braille, "drop")
    (tmp_path / "loud.toml").write_text(LOUD)
    assert main(["experiment", "run", str(tmp_path / "loud.toml"), "--subject", "S01", "--responses", "simulated",
                 "--no-wait", "--quiet", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "amplitude 80 um" in err and "exceeds the display's limits: amplitude_clip at" in err
    assert not list((tmp_path / "out").glob("*.sqlite"))
