"""The pairing key of a UDP display (frame format 3): the description's ``pairing_key_file`` and
``lookahead_s``, the key file's checks (inside the description's folder, no symlink, owner-only
permissions, 32 bytes), ``tactilab device pair``, and the session's record of the description."""

from __future__ import annotations

import json
import os

import pytest
from udp_pairing import KEY, key_file, paired_description

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas.display import DEFAULT_LOOKAHEAD_S, DisplayDescription
from tactilab.experiments.devices import create_pairing_key, description_record, open_display, read_pairing_key
from tactilab.experiments.devices.udp import UdpDisplay

ROW = DisplayDescription.braille_row(n_tractors=2)


def test_a_description_file_names_its_key_and_the_display_reads_it(tmp_path):
    path = paired_description(tmp_path, ROW)
    loaded = DisplayDescription.load(path)
    assert loaded.pairing_key_path() == tmp_path / "display.key"
    display = UdpDisplay(loaded, port=9)  # no network yet: the key is read when the display is made
    try:
        assert display.link.pairing_key == KEY and display.lookahead_s == DEFAULT_LOOKAHEAD_S
    finally:
        display.close()


def test_lookahead_takes_units_in_a_file_and_is_bounded(tmp_path):
    data = json.loads(ROW.to_json())
    data.pop("lookahead_s")
    data["lookahead_ms"] = 20
    (tmp_path / "d.json").write_text(json.dumps(data))
    assert DisplayDescription.load(tmp_path / "d.json").lookahead_s == pytest.approx(0.02)
    with pytest.raises(ValueError, match=r"lookahead_s must lie in \[0, 0.5\]"):
        ROW.replace(lookahead_s=0.6)
    with pytest.raises(ValueError, match=r"lookahead_s must be finite"):
        ROW.replace(lookahead_s=float("nan"))


@pytest.mark.parametrize("name", ["/etc/display.key", "../display.key", "keys/../../display.key", "", "a\x00b"])
def test_a_key_file_name_outside_the_folder_is_refused(name):
    with pytest.raises(ValueError, match=r"pairing_key_file must be a file name relative to the description's folder"):
        ROW.replace(pairing_key_file=name)


def test_the_key_path_is_checked_like_other_file_paths(tmp_path):
    with pytest.raises(ValueError, match=r"pairing_key_file: display 'VirtualBrailleRow' names no pairing key; .*"
                                         r"tactilab device pair KEYFILE"):
        ROW.pairing_key_path()
    with pytest.raises(ValueError, match=r"pairing_key_file: 'display.key' is relative to the description's JSON file, "
                                         r"but this description was not read from one .*--device FILE"):
        ROW.replace(pairing_key_file="display.key").pairing_key_path()
    path = ROW.replace(pairing_key_file="display.key").save(tmp_path / "d.json")
    with pytest.raises(ValueError, match=r"pairing_key_file: .*display.key is not a regular file"):
        DisplayDescription.load(path).pairing_key_path()  # missing
    outside = tmp_path.parent / f"{tmp_path.name}-outside.key"
    key_file(outside.parent, name=outside.name)
    os.symlink(outside, tmp_path / "display.key")
    with pytest.raises(ValueError, match=r"pairing_key_file: 'display.key' must lie inside the description's folder "
                                         r"with no '..' or symlink on the way"):
        DisplayDescription.load(path).pairing_key_path()
    outside.unlink()


def test_a_key_file_others_may_read_is_refused_naming_the_fix(tmp_path):
    path = key_file(tmp_path)
    assert read_pairing_key(path) == KEY
    for mode in (0o640, 0o604, 0o620):
        path.chmod(mode)
        with pytest.raises(ValueError, match=rf"pairing_key_file: .* may be read or written by its group or others "
                                             rf"\(mode {mode:o}\); a pairing key is a secret: run `chmod 600 "):
            read_pairing_key(path)
    path.chmod(0o600)
    short = key_file(tmp_path, KEY[:31], name="short.key")
    with pytest.raises(ValueError, match=r"short.key holds 31 bytes, a pairing key is exactly 32 random bytes"):
        read_pairing_key(short)
    with pytest.raises(ValueError, match=r"--pairing-key: cannot read the pairing key .*none.key"):
        read_pairing_key(tmp_path / "none.key", "--pairing-key")
    os.symlink(path, tmp_path / "link.key")
    with pytest.raises(ValueError, match=r"link.key is not a regular file \(a symlink"):
        read_pairing_key(tmp_path / "link.key")


def test_device_pair_creates_a_private_key_and_never_overwrites(tmp_path, capsys):
    path = tmp_path / "new.key"
    assert cli_main(["device", "pair", str(path)]) == 0
    assert "pairing key written to" in capsys.readouterr().out
    assert (path.stat().st_mode & 0o777) == 0o600 and len(read_pairing_key(path)) == 32
    first = path.read_bytes()
    assert cli_main(["device", "pair", str(path)]) == 2
    assert "exists; a pairing key is never overwritten" in capsys.readouterr().err
    assert path.read_bytes() == first
    with pytest.raises(ValueError, match=r"path: .* exists"):
        create_pairing_key(path)
    assert create_pairing_key(tmp_path / "other.key").read_bytes() != first  # random, not a constant


def test_a_udp_display_needs_a_key(tmp_path):
    with pytest.raises(ValueError, match=r"pairing_key_file: display 'VirtualBrailleRow' names no pairing key"):
        open_display("udp://127.0.0.1:9000", ROW)
    # a session's recorded copy of a paired description does not know the key's folder
    recorded = DisplayDescription.model_validate(description_record(ROW.replace(pairing_key_file="k.key"))[0])
    with pytest.raises(ValueError, match=r"give the description file \(`--device FILE`\)"):
        open_display("udp://127.0.0.1:9000", recorded)


def test_the_recorded_description_leaves_out_default_link_fields():
    """A session recorded before the link fields existed keeps its hash; non-default ones are recorded."""
    data, sha = description_record(ROW)
    assert "pairing_key_file" not in data and "lookahead_s" not in data
    import hashlib

    before = {k: v for k, v in ROW.model_dump(mode="json").items() if k not in ("pairing_key_file", "lookahead_s")}
    assert sha == hashlib.sha256(json.dumps(before, sort_keys=True, separators=(",", ":")).encode()).hexdigest()
    data, other = description_record(ROW.replace(pairing_key_file="k.key", lookahead_s=0.02))
    assert (data["pairing_key_file"], data["lookahead_s"]) == ("k.key", 0.02) and other != sha


def test_the_emulator_needs_its_key(capsys):
    assert cli_main(["device", "emulate", "--port", "0", "--max-seconds", "10ms"]) == 2
    assert "--pairing-key: required; the emulator holds the pairing key its hosts hold" in capsys.readouterr().err
