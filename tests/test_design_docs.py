"""docs/adaptive_design.md: its Python blocks run as written (part faces only), its TOML protocol validates."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "adaptive_design.md"


def test_code_blocks_run_and_use_faces(capsys):
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert blocks
    for block in blocks:
        for line in block.splitlines():
            if line.startswith(("import tactilab", "from tactilab")):
                assert re.match(r"from tactilab\.(data_schemas|forward|inversion|experiments) import ", line), line
        exec(compile(block, str(DOC), "exec"), {})
    out = capsys.readouterr().out
    assert "zx@1mm" in out and "zx@2mm" in out  # the posterior model probabilities are printed


def test_toml_protocol_validates_with_several_varied_fields():
    from tactilab.data_schemas import Protocol

    (block,) = re.findall(r"```toml\n(.*?)```", DOC.read_text(), flags=re.S)
    protocol = Protocol.model_validate(tomllib.loads(block))
    assert protocol.procedure.method == "model_discrimination"
    assert len(protocol.procedure.stimuli()) == 12


def test_docs_cite_only_files_that_exist():
    root = DOC.parents[1]
    for path in re.findall(r"`((?:experiments|cli|benchmarks|tests|docs|data_schemas)/[\w/.]+\.(?:py|md))`",
                           DOC.read_text()):
        assert (root / path).is_file(), path
