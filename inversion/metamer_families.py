"""Stimulus families for tactile metameres: parametrised surface stimuli and their strain readouts.

A family maps a parameter vector (SI units, see ``param_units``) to the strain at receptor
depth; with a linear :class:`~tactilab.forward.ReceptorHypothesis` the map to the readout vector
is a matrix (``matrix``) or an operator with an exact adjoint (``operator``). Readouts are
ordered (depth, component, receptor) in C order (docs/theory.md section 4a for the plane
problem). ``receptors=None`` means the family's grid nodes, ``x_j = (j - n // 2) dx`` as
``LoadToSensor`` places them; families without a grid need receptor positions.

- :class:`SinusoidFamily`: ``H = A sin(2 pi x / p + phase)``, the frictionless indentation of a
  sliding sinusoid (params ``[A]``, m), strain of ``sliding_sinusoid_strain``.
- :class:`IndentationFamily`: periodic frictionless indentation heights at grid nodes (m).
- :class:`GridLoadFamily`: surface tractions at grid nodes (Pa), load-major ``(n_load, *shape)``.
- :class:`TractorFamily`: tangential line loads of a tractor row (N/m, +x), ``|q| <= limit``.

The grid families (:class:`GridLoadFamily`, :class:`IndentationFamily`) live in
:mod:`tactilab.inversion.metamer_grids`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from scipy.sparse.linalg import LinearOperator, aslinearoperator

from tactilab.forward import ReceptorHypothesis, sliding_sinusoid_strain, tractor_row_strain
from tactilab.core import rules
from tactilab.core.memory import check_count

VOIGT = rules.COMPONENTS  # the one Voigt order


def _check_hypothesis(hypothesis) -> ReceptorHypothesis:
    if isinstance(hypothesis, str):
        return ReceptorHypothesis.parse(hypothesis)
    if not isinstance(hypothesis, ReceptorHypothesis):
        raise ValueError(f"hypothesis: expected a ReceptorHypothesis or a string like 'xx,zx@1.25mm', "
                         f"got {type(hypothesis).__name__}")
    return hypothesis


#: bytes per receptor, per depth and per family parameter, of the strain and readout arrays alive at once
#: (6 strain components in float64, and two temporaries of that size: 144; measured peak 141 for
#: xx,zx@1.25mm and 131 per depth for two depths with the wh2008 display's 10 tractors)
RECEPTOR_BYTES = 3 * 6 * 8


def check_receptor_memory(n_receptors: int, n_params: int, n_depths: int, name: str = "receptors") -> int:
    """The memory rule for the receptor count of a dense family's readouts (before any is allocated).

    Parameters
    ----------
    n_receptors : int
        Receptors, count.
    n_params, n_depths : int
        The family's parameters (tractors) and the hypothesis's depths.
    name : str
        The argument that set ``n_receptors`` (``--receptors`` on the command line).

    Raises
    ------
    ValueError
        Above :data:`tactilab.core.memory.MEMORY_LIMIT_BYTES`, naming the largest count that fits.
    """
    per = RECEPTOR_BYTES * int(n_depths) * int(n_params) + 8
    return check_count(n_receptors, per, name, f"receptors (readouts of {int(n_depths)} depth(s) x {int(n_params)} "
                                                f"parameter(s), {per} bytes per receptor)",
                       "fewer depths or a coarser receptor spacing")


def check_families_memory(receptors, hypothesis, *families) -> None:
    """:func:`check_receptor_memory` for the largest dense (1-D) family of a computation, before any of them
    allocates, so the size it names fits them all (the grid families apply FFT operators, not matrices)."""
    dense = [f for f in families if isinstance(f, _DenseFamily)]
    if dense:
        check_receptor_memory(int(np.size(receptors)), max(int(f.n_params) for f in dense), hypothesis.n_depths)


def _x_receptors(receptors, name: str) -> np.ndarray:
    """Receptor x positions (m) of a plane (1-D) family, shape (n,)."""
    if receptors is None:
        raise ValueError(f"receptors: the {name} family has no grid; give receptor x positions in m, "
                         "e.g. np.linspace(-5e-3, 5e-3, 201)")
    r = np.asarray(receptors, dtype=float)
    if r.ndim == 2 and r.shape[1] == 1:
        r = r[:, 0]
    if r.ndim != 1 or r.size == 0 or not np.isfinite(r).all():
        raise ValueError(f"receptors: the {name} family is a plane (1-D) problem; give finite x positions of "
                         f"shape (n,) in m, got shape {np.shape(receptors)}")
    return r


def require_linear(hypothesis: ReceptorHypothesis, what: str = "matrices and operators") -> None:
    """Raise unless every readout of ``hypothesis`` is linear in strain."""
    if not hypothesis.linear:
        raise ValueError(f"hypothesis: {str(hypothesis)!r} holds nonlinear invariants, which have no matrix; "
                         f"{what} need linear components (xx, yy, zz, yz, zx, xy, volumetric)")


def _linear_readout_matrix(strain_of_unit, hypothesis: ReceptorHypothesis, n_params: int) -> np.ndarray:
    """(n_readouts, n_params) from unit-parameter strains (n_depths, n_params, n_rec, 6)."""
    require_linear(hypothesis)
    return hypothesis.readout(strain_of_unit).reshape(n_params, -1).T


def resolve_receptors(receptors, *families):
    """``receptors`` if given, else the grid nodes of the first family that has a grid."""
    if receptors is not None:
        return receptors
    for fam in families:
        r = fam.default_receptors() if hasattr(fam, "default_receptors") else None
        if r is not None:
            return r
    raise ValueError("receptors: none of the families has a grid; give receptor x positions in m, "
                     "e.g. np.linspace(-5e-3, 5e-3, 201)")


@dataclass(frozen=True)
class FamilyStimulus:
    """One stimulus of a family: ``family`` with parameters ``params`` (units: ``family.param_units``).

    Named FamilyStimulus because ``tactilab.data_schemas.Stimulus`` records a presented interval.
    """

    family: object
    params: np.ndarray

    def __post_init__(self) -> None:
        p = np.asarray(self.params, dtype=float).reshape(-1)
        if p.size != self.family.n_params:
            raise ValueError(f"params: the {self.family.name} family takes {self.family.n_params} parameters "
                             f"({', '.join(sorted(set(self.family.param_units)))}), got {p.size}")
        if not np.isfinite(p).all():
            raise ValueError("params: must be finite (no NaN or inf)")
        object.__setattr__(self, "params", p)

    def strain(self, depths, receptors=None) -> np.ndarray:
        """TENSOR Voigt strain, shape (n_depths, n_receptors, 6), at depths (m)."""
        depths = np.atleast_1d(np.asarray(depths, dtype=float))
        for d in depths:
            rules.positive(d, "depths", "m", "give depths below the surface as positive metres")
        return self.family.strain(self.params, depths, receptors)

    def readout(self, hypothesis, receptors=None) -> np.ndarray:
        """Readout vector, shape (n_readouts,), ordered (depth, component, receptor)."""
        h = _check_hypothesis(hypothesis)
        if h.linear:
            return np.asarray(self.family.operator(h, receptors).matvec(self.params))
        return h.readout(self.strain(h.depths, receptors))


@runtime_checkable
class StimulusFamily(Protocol):
    """What metamer analysis needs of a family of stimuli (attributes and methods below)."""

    name: str
    param_units: tuple[str, ...]
    n_params: int
    bounds: tuple[np.ndarray, np.ndarray] | None

    def matrix(self, hypothesis, receptors=None) -> np.ndarray: ...

    def operator(self, hypothesis, receptors=None) -> LinearOperator: ...

    def stimulus(self, params) -> FamilyStimulus: ...


class _DenseFamily:
    """Shared machinery of the small plane families (matrix first, operator from it)."""

    bounds = None
    periodic = False

    def stimulus(self, params) -> FamilyStimulus:
        """The stimulus with these parameters."""
        return FamilyStimulus(self, params)

    def operator(self, hypothesis, receptors=None) -> LinearOperator:
        """The matrix as a LinearOperator (adjoint = transpose)."""
        return aslinearoperator(self.matrix(hypothesis, receptors))

    def default_receptors(self):
        return None


class SinusoidFamily(_DenseFamily):
    """Frictionless sinusoidal indentation ``H = A sin(2 pi x / p + phase)`` (m); params ``[A]``.

    The strain is docs/theory.md 4a's sliding-sinusoid solution (``sliding_sinusoid_strain``),
    independent of E. ``pitch`` in m, ``phase`` in rad, ``nu`` Poisson's ratio.
    """

    name = "sinusoid"
    n_params = 1
    param_units = ("m",)

    def __init__(self, pitch: float, phase: float = 0.0, nu: float = 0.5):
        self.pitch = rules.positive(pitch, "pitch", "m")
        self.phase = float(phase)
        if not np.isfinite(self.phase):
            raise ValueError(f"phase: must be finite (rad), got {phase!r}")
        self.nu = rules.poisson_ratio(nu)

    def with_phase(self, phase: float) -> SinusoidFamily:
        """The same grating at another spatial phase (rad): one frame of a travelling scan."""
        return SinusoidFamily(self.pitch, phase, self.nu)

    def strain(self, params, depths, receptors) -> np.ndarray:
        x = _x_receptors(receptors, self.name)
        check_receptor_memory(x.size, 1, len(depths))
        shift = self.phase * self.pitch / (2 * np.pi)  # H(x + shift) = A sin(2 pi x / p + phase)
        return np.stack([sliding_sinusoid_strain(x, z, float(params[0]), self.pitch, 1.0, shift, self.nu)
                         for z in depths])

    def matrix(self, hypothesis, receptors=None) -> np.ndarray:
        """(n_readouts, 1): readouts per metre of amplitude."""
        h = _check_hypothesis(hypothesis)
        return _linear_readout_matrix(self.strain([1.0], h.depths, receptors)[:, None], h, 1)


class TractorFamily(_DenseFamily):
    """A row of tractors: tangential line loads ``q`` (N/m, +x) at ``tractor_x`` (m); ``|q| <= limit``.

    Strain from ``tractor_row_strain`` (plane strain, Flamant's tangential load; a finite
    ``footprint`` (m) spreads each load uniformly over the tractor's contact width).
    """

    name = "tractors"

    def __init__(self, tractor_x, young_modulus: float, nu: float = 0.5, footprint: float = 0.0,
                 limit: float | None = None):
        tx = np.asarray(tractor_x, dtype=float).reshape(-1)
        if tx.size == 0 or not np.isfinite(tx).all():
            raise ValueError(f"tractor_x: give finite tractor centres in m (at least one), got {tractor_x!r}")
        self.tractor_x = tx
        self.young_modulus = rules.young_modulus(young_modulus)
        self.nu = rules.poisson_ratio(nu)
        self.footprint = float(footprint)
        if not np.isfinite(self.footprint) or self.footprint < 0:
            raise ValueError(f"footprint: must be finite and >= 0 m, got {footprint!r}")
        self.limit = None if limit is None else rules.positive(limit, "limit", "N/m")
        self.n_params = tx.size
        self.param_units = ("N/m",) * tx.size
        self.bounds = None if self.limit is None else (np.full(tx.size, -self.limit), np.full(tx.size, self.limit))

    @classmethod
    def from_display(cls, description, young_modulus: float, row: int = 0) -> TractorFamily:
        """One row of a ``DisplayDescription``: footprint = tractor width, limit = traction x width (N/m)."""
        if isinstance(row, bool) or not isinstance(row, (int, np.integer)) or not 0 <= row < description.rows:
            raise ValueError(f"row: must be an integer in [0, {description.rows - 1}] for display "
                             f"{description.display_id!r}, got {row!r}")
        limit = None
        if description.max_traction_pa is not None:
            limit = description.max_traction_pa * description.tractor_width_m
        return cls(description.tractor_x_m, young_modulus, footprint=description.tractor_width_m, limit=limit)

    def strain(self, params, depths, receptors) -> np.ndarray:
        x = _x_receptors(receptors, self.name)
        check_receptor_memory(x.size, self.n_params, len(depths))
        return np.stack([tractor_row_strain(x, z, self.tractor_x, params, self.young_modulus, self.nu,
                                            self.footprint) for z in depths])

    def matrix(self, hypothesis, receptors=None) -> np.ndarray:
        """(n_readouts, n_tractors): readouts per N/m of each tractor's load."""
        h = _check_hypothesis(hypothesis)
        require_linear(h)
        x = _x_receptors(receptors, self.name)
        check_receptor_memory(x.size, self.n_params, h.n_depths)  # before the offsets and the strain exist
        # unit load of each tractor: one kernel evaluation at every receptor-tractor offset
        offsets = (x[None, :] - self.tractor_x[:, None]).ravel()
        strain = np.stack([tractor_row_strain(offsets, z, [0.0], [1.0], self.young_modulus, self.nu, self.footprint)
                           for z in h.depths])
        return _linear_readout_matrix(strain.reshape(h.n_depths, self.n_params, x.size, 6), h, self.n_params)
