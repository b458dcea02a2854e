"""The pairing key a UDP display shares with its host (docs/udp-frame-format.md, frame format 3).

The key is 32 random bytes in a file of its own, readable by its owner only (like an ssh private
key): the host names it in the display description (``pairing_key_file``), the device (or
``tactilab device emulate --pairing-key FILE``) is given the same file. Only a host holding the
key can arm the device; the key never travels on the link.
"""

from __future__ import annotations

import os
import secrets
import stat
from pathlib import Path

from .link import KEY_SIZE

__all__ = ["read_pairing_key", "create_pairing_key", "description_pairing_key"]


def read_pairing_key(path: str | Path, option: str = "pairing_key_file") -> bytes:
    """The 32 bytes of a pairing key file, after checking that only its owner can read it.

    Parameters
    ----------
    path : str or Path
        The key file (a regular file, no symlink).
    option : str
        The setting that named the file, for errors (``--pairing-key`` on the command line).

    Raises
    ------
    ValueError
        A missing file, a symlink or non-regular file, a file that its group or others may read
        or write (the fix is ``chmod 600``), or a file that is not exactly 32 bytes.
    """
    path = Path(path)
    try:
        info = os.stat(path, follow_symlinks=False)
    except OSError as exc:
        raise ValueError(f"{option}: cannot read the pairing key {path} ({exc.strerror}); create one with "
                         f"`tactilab device pair {path}`") from None
    if not stat.S_ISREG(info.st_mode):
        raise ValueError(f"{option}: {path} is not a regular file (a symlink, folder or device); give the key file "
                         "itself")
    if info.st_mode & 0o077:
        raise ValueError(f"{option}: {path} may be read or written by its group or others (mode "
                         f"{stat.S_IMODE(info.st_mode):o}); a pairing key is a secret: run `chmod 600 {path}`")
    if info.st_size != KEY_SIZE:
        raise ValueError(f"{option}: {path} holds {info.st_size} bytes, a pairing key is exactly {KEY_SIZE} random "
                         f"bytes; create one with `tactilab device pair FILE`")
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0)
    descriptor = os.open(path, flags)
    try:
        key = os.read(descriptor, KEY_SIZE + 1)
    finally:
        os.close(descriptor)
    if len(key) != KEY_SIZE:  # changed between the check and the read
        raise ValueError(f"{option}: {path} changed while it was read; read it again")
    return key


def create_pairing_key(path: str | Path) -> Path:
    """Write a fresh 32-byte pairing key to ``path`` (a new file, mode 600) and return the path.

    Raises
    ------
    ValueError
        If ``path`` exists (a key is never overwritten: the device paired with it would be lost).
    """
    path = Path(path)
    try:
        descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o600)
    except FileExistsError:
        raise ValueError(f"path: {path} exists; a pairing key is never overwritten (the device paired with it "
                         "would be lost): choose another name or delete the old key first") from None
    try:
        os.write(descriptor, secrets.token_bytes(KEY_SIZE))
    finally:
        os.close(descriptor)
    return path


def description_pairing_key(description) -> bytes:
    """The pairing key the description names (:meth:`DisplayDescription.pairing_key_path`), read and checked.

    Raises
    ------
    ValueError
        As ``pairing_key_path`` and :func:`read_pairing_key` raise.
    """
    return read_pairing_key(description.pairing_key_path())
