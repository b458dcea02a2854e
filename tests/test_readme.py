"""The README holds exactly two set-up commands, and .ci/run runs the test one."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _commands() -> dict[str, str]:
    text = (ROOT / "README.md").read_text()
    return dict(re.findall(r"<!-- command: (\w+) -->\n```sh\n(.+?)\n```", text))


def test_readme_has_exactly_two_commands():
    text = (ROOT / "README.md").read_text()
    assert text.count("```sh") == 2
    commands = _commands()
    assert set(commands) == {"demo", "test"}
    assert "tactilab demo" in commands["demo"]
    assert "pytest" in commands["test"] and ".[test]" in commands["test"]
    for cmd in commands.values():
        assert "scripts/find-python" in cmd


def test_ci_extracts_the_readme_test_command():
    script = (ROOT / ".ci" / "run").read_text()
    awk = re.search(r"cmd=\$\(awk '(.+?)' README.md\)", script).group(1)
    out = subprocess.run(["awk", awk, "README.md"], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == _commands()["test"]


def test_find_python_returns_a_new_enough_interpreter():
    out = subprocess.run(["sh", "scripts/find-python"], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    version = subprocess.run([out.stdout.strip(), "-c", "import sys; print(sys.version_info[:2] >= (3, 12))"],
                             capture_output=True, text=True, check=True)
    assert version.stdout.strip() == "True"


def test_find_python_explains_failure(tmp_path):
    # An empty PATH and no pyenv: the script must say what is needed, and fail.
    env = {"PATH": str(tmp_path), "HOME": str(tmp_path), "PYENV_ROOT": str(tmp_path / "none")}
    out = subprocess.run(["/bin/sh", str(ROOT / "scripts" / "find-python")], env=env,
                         capture_output=True, text=True)
    assert out.returncode != 0
    assert "Python >= 3.12" in out.stderr
