"""The Python code blocks of docs/inversion.md import only from the part faces and run as written."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "inversion.md"
BLOCKS = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)


def test_there_are_code_blocks():
    assert BLOCKS


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_code_block_runs(index):
    code = BLOCKS[index]
    for line in code.splitlines():
        if line.startswith(("from tactilab", "import tactilab")):
            module = line.split()[1]
            assert module.count(".") == 1, f"block {index} imports {module}; import from the part face"
    exec(compile(code, f"docs/inversion.md block {index}", "exec"), {"__name__": "docs_block"})
