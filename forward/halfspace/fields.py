"""Stress and strain fields: Hooke's law, deviatoric/volumetric parts, invariants, labels.

Strain here is the symmetric TENSOR strain eps_ij (shear eps_xy = gamma_xy / 2). Papers that
list ENGINEERING shear gamma_ij = 2 eps_ij in a Voigt vector (xx, yy, zz, yz, zx, xy) can be
matched with :func:`to_engineering`. Hooke's law is written in compliance form,
eps = ((1 + nu) sigma - nu tr(sigma) I) / E, so nu = 0.5 is exact (no 1 / (1 - 2 nu)).
"""

from __future__ import annotations

import collections
import math
from collections.abc import Sequence

import numpy as np
import xarray as xr

from tactilab.core import jit
from tactilab.core import rules as check
from tactilab.core.rules import COMPONENTS as VOIGT

#: The shear convention of every strain tactilab returns (recorded in result attributes)
SHEAR_CONVENTION = "tensor shear eps_ij (engineering gamma_ij = 2 eps_ij; see to_engineering)"
INVARIANTS = ("volumetric", "von_mises", "energy_density", "principal", "max_shear")
_PAIRS = {"xx": (0, 0), "yy": (1, 1), "zz": (2, 2), "yz": (1, 2), "zx": (2, 0), "xy": (0, 1)}


def compliance_matrix(young_modulus: float, nu: float) -> np.ndarray:
    """(6, 6) map from Voigt stress (Pa) to Voigt TENSOR strain (dimensionless).

    Parameters
    ----------
    young_modulus : float
        Young's modulus E in Pa (finite, > 0).
    nu : float
        Poisson's ratio in (-1, 0.5].

    Returns
    -------
    ndarray, shape (6, 6), 1/Pa
        Rows and columns in Voigt order (xx, yy, zz, yz, zx, xy); shear rows give tensor
        shear eps_ij (engineering gamma_ij = 2 eps_ij, see :func:`to_engineering`).
    """
    E = check.young_modulus(young_modulus)
    nu = check.poisson_ratio(nu)
    c = np.zeros((6, 6))
    c[:3, :3] = -nu
    np.fill_diagonal(c[:3, :3], 1.0)
    c[3:, 3:] = np.eye(3) * (1.0 + nu)
    return c / E


def output_weights(quantity: str, components: Sequence[str], young_modulus: float, nu: float) -> np.ndarray:
    """Rows mapping Voigt stress to the requested outputs, shape (n_out, 6).

    ``quantity`` is ``"stress"`` (rows of the identity, Pa -> Pa) or ``"strain"`` (rows of
    :func:`compliance_matrix`, Pa -> tensor strain); ``young_modulus`` in Pa.
    """
    idx = [VOIGT.index(c) for c in check.components(components)]
    if quantity == "stress":
        return np.eye(6)[idx]
    if quantity == "strain":
        return compliance_matrix(young_modulus, nu)[idx]
    raise ValueError(f"quantity: must be 'stress' or 'strain', got {quantity!r}")


def to_engineering(strain: xr.DataArray) -> xr.DataArray:
    """Tensor-shear strain -> engineering-shear strain (shear components doubled)."""
    factor = xr.DataArray([2.0 if c in ("yz", "zx", "xy") else 1.0 for c in strain["component"].values],
                          dims="component", coords={"component": strain["component"]})
    out = strain * factor
    out.attrs = dict(strain.attrs, shear_convention="engineering gamma_ij = 2 eps_ij")
    return out


def tensor(field: xr.DataArray) -> np.ndarray:
    """Full symmetric tensors, shape (..., 3, 3), from a 6-component field (component first)."""
    missing = [c for c in VOIGT if c not in field["component"].values]
    if missing:
        raise ValueError(f"field: invariants need all six components, missing {missing}; use components=None")
    data = np.moveaxis(field.sel(component=list(VOIGT)).values, field.get_axis_num("component"), -1)
    t = np.empty(data.shape[:-1] + (3, 3), dtype=data.dtype)
    for k, c in enumerate(VOIGT):
        i, j = _PAIRS[c]
        t[..., i, j] = data[..., k]
        t[..., j, i] = data[..., k]
    return t


def invariants(strain: xr.DataArray, stress: xr.DataArray | None = None) -> xr.Dataset:
    """Receptor-model invariants of a TENSOR strain field (all six components).

    Returns a Dataset with ``volumetric`` (tr eps), ``deviatoric`` (eps - tr/3 I, per
    component), ``von_mises`` (sqrt(2/3 e:e)), ``principal`` (eigenvalues, descending, dim
    ``order``), ``max_shear`` ((eps_1 - eps_3) / 2, tensor shear) and, when ``stress`` is
    given, ``energy_density`` (sigma:eps / 2, J/m^3).
    """
    other_dims = [d for d in strain.dims if d != "component"]
    t = tensor(strain)
    trace = np.trace(t, axis1=-2, axis2=-1)
    dev = t - trace[..., None, None] / 3.0 * np.eye(3)
    vm = np.sqrt(2.0 / 3.0 * np.einsum("...ij,...ij->...", dev, dev))
    principal = np.linalg.eigvalsh(t)[..., ::-1]
    coords = {d: strain[d] for d in strain.coords if set(strain[d].dims) <= set(other_dims)}
    ds = xr.Dataset(coords=coords)
    ds["volumetric"] = (other_dims, trace, {"units": "1", "long_name": "volumetric strain tr(eps)"})
    # the strain's own dimension order (one order for the same fields across files)
    dev_voigt = np.stack([dev[..., _PAIRS[c][0], _PAIRS[c][1]] for c in VOIGT], axis=strain.get_axis_num("component"))
    ds["deviatoric"] = (list(strain.dims), dev_voigt,
                        {"units": "1", "long_name": "deviatoric strain eps - tr(eps) I / 3 (TENSOR shear)",
                         "shear_convention": SHEAR_CONVENTION})
    ds = ds.assign_coords(component=list(VOIGT))
    ds["von_mises"] = (other_dims, vm, {"units": "1", "long_name": "equivalent strain sqrt(2/3 e:e)"})
    ds["principal"] = ([*other_dims, "order"], principal, {"units": "1", "long_name": "principal strains, descending"})
    ds["max_shear"] = (other_dims, (principal[..., 0] - principal[..., 2]) / 2.0,
                       {"units": "1", "long_name": "maximum TENSOR shear strain (eps1 - eps3)/2"})
    if stress is not None:
        s = tensor(stress)
        ds["energy_density"] = (other_dims, 0.5 * np.einsum("...ij,...ij->...", s, t),
                                {"units": "J/m^3", "long_name": "strain energy density sigma:eps/2"})
    return ds


_LABEL_TEMPLATES: collections.OrderedDict = collections.OrderedDict()
_LABEL_TEMPLATES_MAX = 16


def _key_bytes(a) -> bytes | None:
    return None if a is None else np.ascontiguousarray(a, dtype=float).tobytes()


def label(values: np.ndarray, quantity: str, components: Sequence[str], depths: np.ndarray,
          x: np.ndarray, y: np.ndarray | None, points: np.ndarray | None) -> xr.DataArray:
    """Wrap an array (n_depth, n_comp, *grid) or (n_depth, n_comp, n_points) with coordinates.

    The coordinates (and their pandas indexes) are built once per (quantity, components, depths,
    grid or points, shape, dtype) and kept in a small cache of templates holding no field data;
    each call returns a shallow copy carrying ``values`` (not copied) and its own attrs dict.
    """
    key = (quantity, tuple(components), values.shape, values.dtype.str, _key_bytes(depths), _key_bytes(x),
           _key_bytes(y), _key_bytes(points))
    template = _LABEL_TEMPLATES.get(key)
    if template is None:
        placeholder = np.broadcast_to(np.zeros((), values.dtype), values.shape)  # no memory, no data kept
        template = _build_label(placeholder, quantity, components, depths, x, y, points)
        _LABEL_TEMPLATES[key] = template
        if len(_LABEL_TEMPLATES) > _LABEL_TEMPLATES_MAX:
            _LABEL_TEMPLATES.popitem(last=False)
    else:
        _LABEL_TEMPLATES.move_to_end(key)
    return template.copy(deep=False, data=values)


def _frozen(a) -> np.ndarray:
    """A private read-only float copy: cached coordinates must not change under a later caller."""
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def _build_label(values: np.ndarray, quantity: str, components: Sequence[str], depths: np.ndarray,
                 x: np.ndarray, y: np.ndarray | None, points: np.ndarray | None) -> xr.DataArray:
    x, y, depths = _frozen(x), (None if y is None else _frozen(y)), _frozen(depths)
    points = None if points is None else _frozen(points)
    attrs = {"units": "Pa" if quantity == "stress" else "1", "quantity": quantity,
             "long_name": "Cauchy stress (Voigt components)" if quantity == "stress"
             else "strain (Voigt components, TENSOR shear)"}
    if quantity == "strain":
        attrs["shear_convention"] = SHEAR_CONVENTION
    along = {"units": "m", "long_name": "position along x (the scanning direction)"}
    across = {"units": "m", "long_name": "position along y (across the scanning direction)"}
    coords = {"depth": ("depth", depths, {"units": "m", "long_name": "depth below the skin surface",
                                          "positive": "down"}),
              "component": ("component", list(components), {"long_name": "Voigt component"})}
    if points is not None:
        dims = ["depth", "component", "point"]
        coords["x"] = ("point", points[:, 0], along)
        if points.shape[1] > 1:
            coords["y"] = ("point", points[:, 1], across)
    elif y is None:
        dims = ["depth", "component", "x"]
        coords["x"] = ("x", x, along)
    else:
        dims = ["depth", "component", "y", "x"]
        coords["x"] = ("x", x, along)
        coords["y"] = ("y", y, across)
    da = xr.DataArray(values, dims=dims, coords=coords, name=quantity, attrs=attrs)
    for coord in da.coords.values():  # shared by every result built from this template: read-only
        if isinstance(coord.variable.data, np.ndarray):
            coord.variable.data.setflags(write=False)
    return da


def largest_strain(values: np.ndarray, quantity: str, components: Sequence[str], young_modulus: float,
                   nu: float) -> float:
    """A lower bound of the largest principal strain magnitude of a computed field (dimensionless).

    Every entry of a symmetric tensor is bounded by its largest eigenvalue magnitude, so the
    largest ``|eps_ij|`` over the computed components bounds the principal strain from below:
    one max over the field for a strain. For a stress, shear components give
    ``eps_ij = (1 + nu) sigma_ij / E`` exactly, and the normal ones are converted when all three
    were computed (Hooke's law needs the trace).

    Parameters
    ----------
    values : ndarray, shape (n_depths, n_components, ...)
        The field: strain (dimensionless) or stress (Pa), components along axis 1.
    quantity : {"strain", "stress"}
    components : sequence of str
        Voigt names of axis 1.
    young_modulus : float
        E in Pa.
    nu : float
        Poisson's ratio.
    """
    components = check.components(components)
    young_modulus, nu = check.young_modulus(young_modulus), check.poisson_ratio(nu)
    if values.size == 0:
        return 0.0
    index = {c: i for i, c in enumerate(components)}
    if quantity == "strain":  # every component is a strain: one max over the field
        direct, normals = list(index.values()), []
    else:  # shear strains are (1 + nu) sigma_ij / E; the normal ones need all three (the trace)
        direct = [index[c] for c in ("yz", "zx", "xy") if c in index]
        normals = [index[c] for c in ("xx", "yy", "zz")] if {"xx", "yy", "zz"} <= index.keys() else []
    if jit.enabled() and values.dtype in _BITS and values.flags.c_contiguous:  # else no copy: NumPy
        direct_peaks, normal_peaks = _peaks_compiled(values, direct, normals, nu)
    else:
        direct_peaks, normal_peaks = _peaks_numpy(values, direct, normals, nu)
    if quantity == "strain":
        return float("nan") if any(math.isnan(v) for v in direct_peaks) else max(direct_peaks)
    peaks = [(1.0 + nu) / young_modulus * p for p in direct_peaks] + [p / young_modulus for p in normal_peaks]
    # Python's max() drops a NaN after the first element: NaN is the answer, so that the check flags it
    return float("nan") if any(math.isnan(v) for v in peaks) else max(peaks, default=0.0)


def _peaks_numpy(values: np.ndarray, direct: list, normals: list, nu: float) -> tuple[list, list]:
    """max |values[:, k]| for k in ``direct``; max |(1 + nu) s_ii - nu tr| for the three ``normals``.

    Every facade call runs this check: max and min per component, no field-sized temporaries but
    one work array for the normal strains (fancy indexing and abs copies made it cost as much as
    the whole spectral solve at 256^2). The NumPy twin of :func:`_peaks_compiled`.
    """
    direct_peaks = [_peak(values[:, k]) for k in direct]
    normal_peaks = []
    if normals:
        sxx, syy, szz = (values[:, k] for k in normals)
        trace = sxx + syy
        trace += szz
        trace *= nu
        work = np.empty_like(trace)
        for normal in (sxx, syy, szz):  # eps_ii E = (1 + nu) sigma_ii - nu trace
            np.multiply(normal, 1.0 + nu, out=work)
            work -= trace
            normal_peaks.append(_peak(work))
    return direct_peaks, normal_peaks


#: The integer type of each float type's bit pattern, and the mask that clears the sign bit
_BITS = {np.dtype(np.float64): (np.int64, 0x7FFF_FFFF_FFFF_FFFF), np.dtype(np.float32): (np.int32, 0x7FFF_FFFF)}
_BLOCK = 512  # normal strains per block of the compiled kernel (its scratch stays in L1)


def _peaks_compiled(values: np.ndarray, direct: list, normals: list, nu: float) -> tuple[list, list]:
    """:func:`_peaks_numpy` in one compiled pass over a C-contiguous field, with the same results.

    ``max |x|`` is taken on the bit patterns with the sign bit cleared, as integers: for
    non-negative floats they order as the numbers do, and a NaN's pattern lies above infinity's,
    so a NaN anywhere is the maximum (exact NaN detection, and an integer maximum vectorises
    where a floating-point one that must keep NaN does not).
    """
    itype, mask = _BITS[values.dtype]
    field = values.reshape(values.shape[0], values.shape[1], -1)  # C-contiguous: a view
    scratch = np.empty(_BLOCK, field.dtype)
    peaks = np.zeros(len(direct) + len(normals), itype)
    one_plus_nu, nu_ = field.dtype.type(1.0 + nu), field.dtype.type(nu)  # NumPy's float32 arithmetic
    _peaks_kernel(field, field.view(itype), np.array(direct, np.int64), np.array(normals, np.int64),
                  one_plus_nu, nu_, itype(mask), scratch, scratch.view(itype), peaks)
    found = [float(p) for p in peaks.view(field.dtype)]
    return found[:len(direct)], found[len(direct):]


@jit.njit
def _peaks_kernel(field, bits, direct, normals, one_plus_nu, nu, mask, scratch, scratch_bits,
                  peaks):  # pragma: no cover - compiled by numba
    """peaks[k]: max of ``bits & mask`` over component direct[k], then over each of the three
    normal strains (1 + nu) s_ii - nu tr (times E), computed block by block into ``scratch``.

    Indices run from 0 in every loop (slices per block): a computed index such as ``start + j``
    keeps numba's negative-index check in the loop, which stops it vectorising (4x slower).
    """
    n, first = field.shape[2], direct.shape[0]
    for d in range(field.shape[0]):
        for k in range(first):
            row, peak = bits[d, direct[k]], peaks[k]
            for i in range(n):
                v = row[i] & mask
                if v > peak:
                    peak = v
            peaks[k] = peak
        if normals.shape[0] == 0:
            continue
        for start in range(0, n, scratch.shape[0]):
            stop = min(n, start + scratch.shape[0])
            xx = field[d, normals[0], start:stop]
            yy = field[d, normals[1], start:stop]
            zz = field[d, normals[2], start:stop]
            for m in range(3):
                own = xx if m == 0 else (yy if m == 1 else zz)
                for j in range(stop - start):  # NumPy's order: ((xx + yy) + zz) nu, then own (1 + nu) - that
                    scratch[j] = own[j] * one_plus_nu - (xx[j] + yy[j] + zz[j]) * nu
                peak = peaks[first + m]
                for j in range(stop - start):
                    v = scratch_bits[j] & mask
                    if v > peak:
                        peak = v
                peaks[first + m] = peak


def _peak(a: np.ndarray) -> float:
    """``max |a|`` without a temporary (NaN if ``a`` holds one)."""
    high, low = float(a.max()), float(a.min())
    return float("nan") if math.isnan(high) or math.isnan(low) else max(high, -low)
