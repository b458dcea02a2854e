"""docs/model_comparison.md: its Python blocks run as written and import only from the part faces."""

from __future__ import annotations

import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "model_comparison.md"


def test_code_blocks_run_and_use_faces(capsys):
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert len(blocks) == 2
    for block in blocks:
        for line in block.splitlines():
            if line.startswith(("import tactilab", "from tactilab")):
                assert re.match(r"from tactilab\.(data_schemas|forward|inversion|experiments) import ", line), line
        exec(compile(block, str(DOC), "exec"), {})
    out = capsys.readouterr().out
    assert "95 % interval" in out and "zx@1mm vs zx@3mm" in out and "inf trials (identical predictions)" in out


def test_docs_cite_only_files_that_exist():
    root = DOC.parents[1]
    for path in re.findall(r"`((?:experiments|cli|benchmarks|tests|docs)/[\w/.]+\.(?:py|md))`", DOC.read_text()):
        assert (root / path).is_file(), path
