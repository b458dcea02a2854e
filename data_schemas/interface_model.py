"""The interface model a recording was made with, stated in the recording itself.

A simulated recording says which interface model made it (``"exact"``, ``"linear"`` or
``"modulation"``, docs/scenes.md) and the error of the other models for its scene, where it was
estimated. netCDF files carry it as attributes (:func:`model_attrs`); every format (netCDF,
Parquet, JSON) also carries it at the end of the recording's ``description``
(:func:`model_statement`), which :func:`recording_model` reads back.
"""

from __future__ import annotations

import math
import pathlib
import re

#: netCDF attribute names
MODEL_ATTR, TOL_ATTR, BASIS_ATTR, REASON_ATTR, ERROR_PREFIX = (
    "contact_model", "contact_model_tol", "contact_model_error_basis", "contact_model_reason", "contact_model_error_")
_STATEMENT = re.compile(r"\[interface model: (?P<model>\w+); tol (?P<tol>[^;]+); model errors: (?P<errors>[^(\]]*)"
                        r"\((?P<basis>[^)]*)\)\]")


def model_attrs(model: str, tol: float, errors: dict, basis: str, reason: str) -> dict:
    """netCDF attributes stating the interface model (errors as ``contact_model_error_<model>``)."""
    attrs = {MODEL_ATTR: model, TOL_ATTR: float(tol), BASIS_ATTR: basis, REASON_ATTR: reason}
    attrs.update({f"{ERROR_PREFIX}{name}": float(err) for name, err in errors.items()})
    return attrs


def model_statement(model: str, tol: float, errors: dict, basis: str) -> str:
    """The statement appended to a recording's description, e.g.
    ``[interface model: exact; tol 0.01; model errors: linear 0.31, modulation 0.5 (measured ...)]``."""
    listed = ", ".join(f"{name} {err:.3g}" for name, err in errors.items()) or "none "
    return f"[interface model: {model}; tol {tol:g}; model errors: {listed.strip()} ({basis})]"


def recording_model(recording, path=None) -> dict | None:
    """The interface model a recording states, or None when it states none (older recordings).

    Parameters
    ----------
    recording : Recording
        Its ``description`` is read.
    path : path, optional
        A ``.nc`` file's attributes are read first.

    Returns
    -------
    dict or None
        ``"model"`` (str), ``"tol"`` (float), ``"errors"`` (model -> relative error of the sensor
        signal) and ``"basis"`` (how the errors were obtained).
    """
    if path is not None and pathlib.Path(path).suffix == ".nc":
        import xarray as xr

        with xr.open_dataset(path, engine="h5netcdf") as ds:
            attrs = dict(ds.attrs)
        if MODEL_ATTR in attrs:
            errors = {k.removeprefix(ERROR_PREFIX): float(v) for k, v in attrs.items()
                      if k.startswith(ERROR_PREFIX) and k != BASIS_ATTR}
            return {"model": str(attrs[MODEL_ATTR]), "tol": float(attrs.get(TOL_ATTR, math.nan)), "errors": errors,
                    "basis": str(attrs.get(BASIS_ATTR, ""))}
    found = _STATEMENT.search(getattr(recording, "description", "") or "")
    if found is None:
        return None
    errors = {}
    for item in found["errors"].split(","):
        parts = item.split()
        if len(parts) == 2:
            errors[parts[0]] = float(parts[1])
    return {"model": found["model"], "tol": float(found["tol"]), "errors": errors, "basis": found["basis"]}


def model_mismatch(stated: dict | None, assumed: str, what: str) -> str | None:
    """One line saying that ``what`` assumes the ``assumed`` model where the recording was made with
    another, with that model's error for the recording's scene; None when they agree or nothing is stated."""
    if stated is None or stated["model"] == assumed:
        return None
    err = stated["errors"].get(assumed)
    size = (f"the {assumed} model's error for this scene is {err:.2g} of the signal ({stated['basis']})"
            if err is not None else f"the recording gives no error of the {assumed} model for its scene")
    return (f"the recording was made with the {stated['model']!r} interface model but {what} assumes the "
            f"{assumed!r} model; {size}")
