"""CF-style metadata on every netCDF file tactilab writes (the CF conventions, version 1.10).

Every writer of the package goes through :func:`write_netcdf` (or
:func:`~tactilab.core.batch.write_netcdf_atomic`), which applies :func:`cf_ready`:

- global attributes ``Conventions = "CF-1.10"`` and ``tactilab_version`` (the package that wrote
  the file);
- every variable and coordinate gets a ``long_name`` (its own, else a generic one for the
  indices every file shares: ``chain``, ``draw``, ...; else its name in words);
- a coordinate named ``depth`` gets ``positive = "down"`` (CF: depth grows into the skin);
- an integer coordinate along its own dimension (an index) gets ``units = "1"``;
- nothing else is changed: units are the writer's to state, in SI (``"1"`` for dimensionless
  quantities, as CF writes it). :func:`cf_problems` lists what a file still lacks, which the
  tests check for every writer (``tests/test_cf_metadata.py``).
"""

from __future__ import annotations

import pathlib

from .version import package_version

__all__ = ["CONVENTIONS", "cf_ready", "cf_problems", "write_netcdf"]

#: the CF version the files follow
CONVENTIONS = "CF-1.10"

#: long names (and units) of the indices and coordinates many files share
_SHARED = {
    "chain": ("1", "Markov chain (independent ensemble) index"),
    "draw": ("1", "posterior draw index within a chain"),
    "depth": ("m", "depth below the skin surface"),
    "time": ("s", "time"),
    "data_id": ("1", "observation index"),
    "trial": ("1", "trial index"),
    "order": ("1", "order of the principal values (descending)"),
}


def _nodes(data):
    """The datasets of a Dataset (itself) or of every node of a DataTree."""
    import xarray as xr

    if isinstance(data, xr.DataTree):
        return [node.dataset for node in data.subtree], [node for node in data.subtree]
    if isinstance(data, xr.Dataset):
        return [data], [data]
    raise ValueError(f"data: must be an xarray Dataset or DataTree, got {type(data).__name__}; wrap arrays in "
                     "an xarray.Dataset first")


def cf_ready(data):
    """A shallow copy of ``data`` with the CF attributes of the module docstring set.

    Parameters
    ----------
    data : xarray.Dataset or xarray.DataTree

    Returns
    -------
    xarray.Dataset or xarray.DataTree
        The same values (not copied), with the attributes added; ``data`` is not modified.

    Raises
    ------
    ValueError
        If ``data`` is neither a Dataset nor a DataTree.
    """
    import xarray as xr

    _nodes(data)  # refuses anything but a Dataset or DataTree
    out = data.copy(deep=False)
    if isinstance(out, xr.DataTree):
        for node in out.subtree:
            node.dataset = _dataset_ready(node.to_dataset(inherit=False))  # inherited coordinates stay the parent's
    else:
        out = _dataset_ready(out)
    out.attrs.update(Conventions=CONVENTIONS, tactilab_version=package_version())
    return out


def _dataset_ready(ds):
    ds = ds.copy(deep=False)
    for name, var in ds.variables.items():
        attrs = dict(var.attrs)
        units, long_name = _SHARED.get(str(name), (None, None))
        if "long_name" not in attrs:
            attrs["long_name"] = long_name or str(name).replace("_", " ")
        if units is not None and "units" not in attrs and var.dtype.kind in "iuf":
            attrs["units"] = units
        elif (name,) == var.dims and var.dtype.kind in "iu" and "units" not in attrs:
            attrs["units"] = "1"  # an integer index along its own dimension: a count
        if name == "depth":
            attrs["positive"] = "down"
        var.attrs = attrs
    return ds


def cf_problems(data) -> list[str]:
    """What a dataset or tree lacks for this package's CF rules, one line per problem (empty: none).

    Checked: the global ``Conventions`` and ``tactilab_version``; ``long_name`` on every variable
    and coordinate; ``units`` on every numeric one; ``positive = "down"`` on ``depth``.
    """
    datasets, nodes = _nodes(data)
    problems = [f"global attribute {key} missing" for key in ("Conventions", "tactilab_version")
                if key not in data.attrs]
    for ds, node in zip(datasets, nodes):
        where = getattr(node, "path", "/")
        for name, var in ds.variables.items():
            if "long_name" not in var.attrs:
                problems.append(f"{where} {name}: no long_name")
            if var.dtype.kind in "iuf" and "units" not in var.attrs:
                problems.append(f"{where} {name}: no units")
            if name == "depth" and var.attrs.get("positive") != "down":
                problems.append(f"{where} depth: positive is not 'down'")
    return problems


def write_netcdf(data, path) -> pathlib.Path:
    """Write ``data`` to netCDF4 (h5netcdf) at ``path`` with the CF attributes of :func:`cf_ready`.

    Parameters
    ----------
    data : xarray.Dataset or xarray.DataTree
    path : str or pathlib.Path

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = pathlib.Path(path)
    cf_ready(data).to_netcdf(path, engine="h5netcdf")
    return path
