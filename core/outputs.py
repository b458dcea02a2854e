"""What tactilab writes: files that stay inside their output folder, replaced whole, never
through a symlink, and printed text with no terminal control characters.

Names in a file written by someone else (a session's subject, a protocol's name) become parts
of output paths and of printed lines. :func:`output_path` joins such names under an output folder
and refuses any result that leaves it; :func:`write_atomic` writes a file through a temporary
file in the same folder and ``os.replace``, and refuses a symlink (dangling or not) at the
target, so ``--force`` replaces a file and never writes through a link to another one;
:func:`printable` escapes control characters (``\\x1b`` and the like) before text reaches a
terminal.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Callable
from pathlib import Path

__all__ = ["new_file", "output_path", "printable", "write_atomic"]


def output_path(out: str | Path, *parts: str, option: str = "--out") -> Path:
    """``out / part / ...``, checked to resolve inside ``out`` and to be no symlink.

    Parameters
    ----------
    out : path
        The output folder (it need not exist yet).
    *parts : str
        Folder and file names below ``out``; each must be one plain name (no separator, not
        ``.`` or ``..``).
    option : str
        The option that named ``out`` (for messages).

    Raises
    ------
    ValueError
        If a part is not a plain name, the path resolves outside ``out`` (a symlinked folder
        that points elsewhere), or the target is a symlink.
    """
    for part in parts:
        if (not isinstance(part, str) or part in ("", ".", "..") or "/" in part or "\\" in part
                or "\x00" in part or os.sep in part or (os.altsep and os.altsep in part)):
            raise ValueError(f"{option}: the output name {printable(str(part))!r} is not one plain file name; "
                             "the session or protocol that supplied it was edited, restore it from a copy")
    root = Path(out).resolve()
    target = Path(out).joinpath(*parts)
    if os.path.islink(target):
        raise ValueError(f"{option}: {printable(str(target))} is a symlink; tactilab never writes through a "
                         "link, remove it or export to another folder")
    if not target.resolve().is_relative_to(root):
        raise ValueError(f"{option}: {printable(str(target))} resolves outside {printable(str(root))} (a "
                         "symlinked folder); export to a folder without links")
    return target


def write_atomic(target: str | Path, write: Callable[[Path], object], *, overwrite: bool = True,
                 option: str = "--out") -> Path:
    """Write ``target`` whole: ``write(temporary_path)`` then ``os.replace`` into place.

    A reader sees the old file or the new one, never half of it; a symlink at ``target`` is
    refused (dangling or not), so its target is never written.

    Parameters
    ----------
    target : path
        The file to write; its folder must exist.
    write : callable
        ``write(path)`` writes the whole content to ``path`` (a fresh file in the same folder).
    overwrite : bool
        Replace an existing file (``--force``); otherwise an existing file is refused.
    option : str
        The option that named the folder (for messages).

    Raises
    ------
    ValueError
        If ``target`` is a symlink, or exists and ``overwrite`` is False.
    """
    target = new_file(target, overwrite, option)
    temporary = target.with_name(f".{target.name}.{secrets.token_hex(8)}.tmp")
    # O_EXCL: never an existing file or link; mode 0o666 less the umask, as for any new file
    os.close(os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o666))
    try:
        write(Path(temporary))
        with open(temporary, "rb") as handle:
            os.fsync(handle.fileno())
        if os.path.islink(target):  # a link planted while writing is refused too
            raise ValueError(f"{option}: {printable(str(target))} became a symlink while it was written; "
                             "remove it or export to another folder")
        os.replace(temporary, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise
    return target


def new_file(target: str | Path, overwrite: bool = False, option: str = "--out") -> Path:
    """``target``, checked before anything is written to it: no symlink, and no existing file unless ``overwrite``.

    The one rule for a file a command writes into a folder that holds other files (a figure next to a
    session): an earlier run's file is never replaced silently, ``--force`` replaces it.

    Raises
    ------
    ValueError
        If ``target`` is a symlink, or exists and ``overwrite`` is False.
    """
    target = Path(target)
    if os.path.islink(target):
        raise ValueError(f"{option}: {printable(str(target))} is a symlink; tactilab never writes through a "
                         "link, remove it or export to another folder")
    if os.path.lexists(target) and not overwrite:
        raise ValueError(f"{option}: {printable(str(target))} already exists; export to another folder, or add "
                         "--force to replace it")
    return target


def printable(text: str) -> str:
    """``text`` with every control character (C0, DEL, C1) escaped as ``\\xNN``; tabs and
    newlines too, so a field prints on one line and cannot move the cursor or recolour the
    terminal."""
    return "".join(c if c.isprintable() or c == " " else c.encode("unicode_escape").decode("ascii")
                   for c in str(text))
