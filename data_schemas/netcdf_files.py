"""A netCDF-4 (HDF5) file is read only when it holds all of its own data.

HDF5 lets a file point elsewhere: a dataset may keep its bytes in other files (external
storage: any local file, read as the dataset's values), be a virtual dataset mapped from other
files, or a group may hold an external link to an object in another file. Reading such a
"recording" would read whatever local file it names. :func:`check_self_contained` walks the
file's links without following any and refuses all three before xarray opens it.
"""

from __future__ import annotations

import pathlib

__all__ = ["check_self_contained"]


def check_self_contained(path: str | pathlib.Path, option: str = "path") -> None:
    """Refuse a netCDF-4/HDF5 file that stores data outside itself.

    Parameters
    ----------
    path : path
        The ``.nc`` file.
    option : str
        The argument that named it (for messages).

    Raises
    ------
    ValueError
        If a dataset uses external storage or is virtual, or a group holds an external link;
        the message names the object and the fix. A file HDF5 cannot open is left to the reader.
    """
    import h5py

    try:
        handle = h5py.File(path, "r")
    except OSError:
        return  # not HDF5 (or unreadable): the netCDF reader reports it in its own words
    with handle:
        pending, seen = [handle], set()
        while pending:
            group = pending.pop()
            for name in group:
                link = group.get(name, getlink=True)
                where = f"{group.name.rstrip('/')}/{name}"
                if isinstance(link, h5py.ExternalLink):
                    _refuse(path, option, f"an external link {where!r} to another file")
                if not isinstance(link, h5py.HardLink):
                    continue  # a soft link names an object of this file, reached by its hard link
                item = group[name]
                if isinstance(item, h5py.Dataset):
                    if item.external:
                        _refuse(path, option, f"dataset {where!r} stored in external files")
                    if item.is_virtual:
                        _refuse(path, option, f"virtual dataset {where!r} mapped from other files")
                elif isinstance(item, h5py.Group) and item.id.addr not in seen:
                    seen.add(item.id.addr)
                    pending.append(item)


def _refuse(path, option: str, what: str) -> None:
    raise ValueError(f"{option}: {str(path)!r} holds {what}; a recording must hold all of its own data "
                     "(reading it would read other local files); write it with write_recording")
