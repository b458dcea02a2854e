"""Helpers shared by the command modules (edge handling only, no science)."""

from __future__ import annotations

from pathlib import Path


def make_out(folder: Path, option: str = "--out") -> Path:
    """Create the output folder first, so a bad path fails before the computation, in one line."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OSError(f"{option}: cannot create the output folder {str(folder)!r} ({exc.strerror or exc}); "
                      "choose a writable folder") from None
    return folder
