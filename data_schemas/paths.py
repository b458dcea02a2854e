"""Files a record names next to its own file (a protocol's conditions CSV, a scene's topography).

One rule for every such name: relative, inside the folder of the file that names it, no ``..`` and
no symlink anywhere on the way, and a regular file at the end. A file written by someone else
cannot then make tactilab read outside the folder it was handed.
"""

from __future__ import annotations

import os
from pathlib import Path


def file_inside(folder: str | Path, name: str, *, key: str, owner: str, what: str) -> Path:
    """``folder / name``, checked: relative, inside ``folder``, a regular file, no symlink on the way.

    Parameters
    ----------
    folder : path
        The folder of the file that names ``name`` (a protocol, a scene).
    name : str
        The relative file name, as written in that file.
    key : str
        The key that holds ``name`` (``"procedure.conditions"``, ``"surface.path"``), for messages.
    owner : str
        What names it (``"protocol"``, ``"scene"``), for messages.
    what : str
        What the file is (``"CSV"``, ``"topography file"``), for messages.

    Raises
    ------
    ValueError
        For an absolute name, a path that leaves the folder or passes a symlink, or a missing
        or non-regular file.
    """
    folder = Path(folder)
    if not isinstance(name, str) or not name or Path(name).is_absolute() or "\x00" in name:
        raise ValueError(f"{key}: must be a file name relative to the {owner}'s folder, got "
                         f"{name!r}; put the {what} next to the {owner}")
    target = folder / name
    walked = folder
    for part in Path(name).parts:  # no symlink anywhere below the owner's folder
        walked = walked / part
        if part == ".." or os.path.islink(walked):
            raise ValueError(f"{key}: {name!r} must lie inside the {owner}'s folder with no "
                             f"'..' or symlink on the way; copy the {what} next to the {owner}")
    if not target.resolve().is_relative_to(folder.resolve()):
        raise ValueError(f"{key}: {name!r} resolves outside the {owner}'s folder; copy the {what} "
                         f"next to the {owner}")
    if not target.is_file():
        raise ValueError(f"{key}: {target} is not a regular file (missing, or a folder or "
                         f"device); give the {what}'s name relative to the {owner}")
    return target
