"""docs/metameres.md: its Python blocks run as written and import only from the part faces."""

from __future__ import annotations

import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "metameres.md"


def test_code_blocks_run_and_use_faces(capsys):
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert blocks
    for block in blocks:
        for line in block.splitlines():
            if line.startswith(("import tactilab", "from tactilab")):
                assert re.match(r"from tactilab\.(data_schemas|forward|inversion|experiments) import ", line), line
        exec(compile(block, str(DOC), "exec"), {})
    out = capsys.readouterr().out
    assert "residual 0.1000" in out and "scan rms" in out
