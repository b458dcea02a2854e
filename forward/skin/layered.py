"""Layered skin: elastic layers bonded on a rigid base (bone) or on an elastic half-space.

>>> pulp = LayeredHalfSpace([Layer(thickness=4e-3, E=0.1e6, nu=0.5)], base="rigid")   # m, Pa
>>> pulp.strain(load, depth=3e-3, components=("zz",))       # like HalfSpace.strain
>>> solve_contact(pulp, gap, spacing, normal_force=1.0, periodic=True)

Per wavenumber the fields are exact (propagation through the layers with decaying exponentials
only, docs/theory.md section 6); ``nu = 1/2`` is exact in every layer. The faces are those of
:class:`tactilab.forward.halfspace.HalfSpace`: :meth:`~LayeredHalfSpace.stress`,
:meth:`~LayeredHalfSpace.strain`, :meth:`~LayeredHalfSpace.operator` and
:meth:`~LayeredHalfSpace.surface_compliance` (the contact solver's skin protocol).
"""

from __future__ import annotations

import collections
import hashlib
from dataclasses import dataclass

import numpy as np

from tactilab.core import rules as check
from tactilab.forward.halfspace import HalfSpace, compliance_matrix

from .layered_multipliers import transfer_matrix
from .prony import Prony
from .propagator import Stack, surface_amplitudes

#: memory for the surface amplitudes of recent wavenumber arrays (a contact grid's bands, reused per block)
AMPLITUDE_CACHE_BYTES = 128 * 2**20


@dataclass(frozen=True)
class Layer:
    """One layer of a skin: elastic, or viscoelastic when its modulus is a :class:`Prony` series.

    Parameters
    ----------
    thickness : float
        Thickness in m (finite, > 0).
    E : float or Prony
        Young's modulus in Pa, or the layer's relaxation modulus E(t) (Pa, s) as a Prony series;
        a viscoelastic layer goes into a :class:`ViscoelasticLayeredHalfSpace`.
    nu : float
        Poisson's ratio in (-1, 0.5], constant in time; 0.5 (incompressible) is exact.
    """

    thickness: float
    E: float | Prony
    nu: float = 0.5

    def __post_init__(self) -> None:
        object.__setattr__(self, "thickness", check.positive(self.thickness, "thickness", "m",
                                                             "give the layer's thickness in m (e.g. 4e-3 for pulp)"))
        if not isinstance(self.E, Prony):
            object.__setattr__(self, "E", check.young_modulus(self.E, "E"))
        object.__setattr__(self, "nu", check.poisson_ratio(self.nu, "nu"))

    @property
    def is_viscoelastic(self) -> bool:
        """True when the modulus is a Prony series."""
        return isinstance(self.E, Prony)

    @property
    def G(self) -> float:
        """Shear modulus in Pa (an elastic layer's; a viscoelastic one has :meth:`complex_modulus`)."""
        if self.is_viscoelastic:
            raise ValueError(f"E: a viscoelastic layer ({self.E!r}) has no single shear modulus; use "
                             "complex_modulus(omega) or elastic('instantaneous' | 'relaxed')")
        return self.E / (2.0 * (1.0 + self.nu))

    def complex_modulus(self, omega) -> np.ndarray:
        """E*(omega) in Pa (complex) at angular frequencies ``omega`` (rad/s); the constant E when elastic."""
        if self.is_viscoelastic:
            return self.E.complex_modulus(omega)
        return np.full(np.shape(omega), complex(self.E))

    def elastic(self, limit: str) -> "Layer":
        """The elastic layer of the ``"instantaneous"`` (E(0)) or ``"relaxed"`` (E_inf) modulus."""
        if limit not in ("instantaneous", "relaxed"):
            raise ValueError(f"limit: must be 'instantaneous' or 'relaxed', got {limit!r}")
        if not self.is_viscoelastic:
            return self
        return Layer(self.thickness, self.E.E_0 if limit == "instantaneous" else self.E.E_inf, self.nu)


def as_layers(layers) -> tuple[Layer, ...]:
    """A non-empty tuple of :class:`Layer` (one Layer is a list of one), or a clear error."""
    if isinstance(layers, Layer):
        layers = [layers]
    try:
        layers = tuple(layers)
    except TypeError:
        raise ValueError(f"layers: expected a list of Layer(thickness, E, nu), got {type(layers).__name__}; "
                         "e.g. [Layer(4e-3, 1e5, 0.5)]") from None
    if not layers or not all(isinstance(layer, Layer) for layer in layers):
        raise ValueError(f"layers: expected a non-empty list of Layer(thickness, E, nu), got {layers!r}; "
                         "e.g. [Layer(4e-3, 1e5, 0.5)]")
    return layers


class LayeredHalfSpace:
    """Elastic layers, top first, bonded to each other and to a base.

    Parameters
    ----------
    layers : sequence of Layer
        At least one layer, the skin surface on top of the first.
    base : "rigid" or HalfSpace
        ``"rigid"``: the last layer is bonded to an immovable base (bone); a ``HalfSpace(E, nu)``:
        the last layer lies bonded on that elastic half-space.
    """

    def __init__(self, layers, base="rigid"):
        layers = as_layers(layers)
        viscous = [n for n, layer in enumerate(layers) if layer.is_viscoelastic]
        if viscous:
            raise ValueError(f"layers[{viscous[0]}]: a LayeredHalfSpace is elastic, but this layer's modulus is a "
                             "Prony series; use ViscoelasticLayeredHalfSpace(layers, base) for viscoelastic layers")
        if not (isinstance(base, HalfSpace) or (isinstance(base, str) and base == "rigid")):
            raise ValueError(f"base: must be 'rigid' or a HalfSpace(E, nu), got {base!r}; "
                             "use base='rigid' for bone, HalfSpace(E, nu) for a deeper soft tissue")
        self.layers = layers
        self.base = base
        self._amplitude_cache: collections.OrderedDict = collections.OrderedDict()
        self._stack = Stack(np.array([layer.thickness for layer in layers]), np.array([layer.G for layer in layers]),
                            np.array([layer.nu for layer in layers]),
                            None if base == "rigid" else (base.E / (2.0 * (1.0 + base.nu)), base.nu))

    def __repr__(self) -> str:
        return f"LayeredHalfSpace(layers={list(self.layers)!r}, base={self.base!r})"

    @property
    def rigid_base(self) -> bool:
        """True when the last layer is bonded to a rigid base."""
        return isinstance(self.base, str)

    @property
    def thickness(self) -> float:
        """Total thickness of the layers, m."""
        return self._stack.total

    def material_at(self, depth: float) -> tuple[float, float]:
        """``(E, nu)`` of the material at ``depth`` (m); an interface belongs to the layer above.

        Raises
        ------
        ValueError
            For a depth inside the rigid base.
        """
        depth = check.depth(depth)
        j = self._stack.locate(depth)
        if j < len(self.layers):
            return self.layers[j].E, self.layers[j].nu
        if self.rigid_base:
            raise ValueError(f"depth: {depth!r} m lies in the rigid base, below the layers' {self.thickness!r} m; "
                             "give depths within the layers (the base does not deform)")
        return self.base.E, self.base.nu

    # -- the contact solver's protocol ---------------------------------------------------------
    def surface_compliance(self, kx, ky=None) -> np.ndarray:
        """Surface tractions to surface displacements per wavenumber, as :meth:`HalfSpace.surface_compliance`.

        Parameters
        ----------
        kx, ky : array_like
            Angular wavenumbers (rad/m) along x and y, broadcast together; ``ky=None``: plane strain.

        Returns
        -------
        ndarray, complex, shape ``(..., 3, 3)`` (``(..., 2, 2)`` in plane strain), m/Pa per unit Fourier
            amplitude: rows ``(uz, ux, uy)``, columns ``(p, qx, qy)``; Hermitian (Betti). At ``k = 0``
            on a rigid base the laterally constrained compression and shear of the layers,
            ``sum h (1 + nu)(1 - 2 nu) / (E (1 - nu))`` normal and ``sum h / G`` tangential; on a
            half-space base 0 (a rigid shift, as for the half-space).
        """
        kx = check.finite_array(kx, "kx", "rad/m")
        plane = ky is None
        if plane:
            k, nx, ny = np.abs(kx), np.sign(kx), np.zeros_like(kx)
        else:
            kx, ky = np.broadcast_arrays(kx, check.finite_array(ky, "ky", "rad/m"))
            k = np.hypot(kx, ky)
            with np.errstate(invalid="ignore", divide="ignore"):
                nx, ny = np.where(k > 0, kx / k, 0.0), np.where(k > 0, ky / k, 0.0)
        live = k > 0
        amp = self._amplitudes(k, live)
        out = np.zeros(k.shape + (3, 3), dtype=complex)
        n = (nx, ny)
        t = (-ny, nx)
        out[..., 0, 0] = amp["Wp"]
        for a in range(2):
            out[..., 0, a + 1] = 1j * amp["Wq"] * n[a]
            out[..., a + 1, 0] = 1j * amp["Up"] * n[a]
            for b in range(2):
                out[..., a + 1, b + 1] = -amp["Uq"] * n[a] * n[b] + amp["V"] * t[a] * t[b]
        if self.rigid_base:
            st = self._stack
            normal = np.sum(st.thickness * (1 - 2 * st.nu) / (2 * st.G * (1 - st.nu)))  # complex moduli too
            shear = np.sum(st.thickness / st.G)
            out[~live] = np.diag([normal, shear, shear])
        return out[..., :2, :2] if plane else out

    def transfer(self, kx, ky, depth: float, quantity: str = "stress") -> np.ndarray:
        """The exact multipliers from surface tractions to stress or strain at ``depth``, per wavenumber.

        Parameters
        ----------
        kx, ky : array_like
            Angular wavenumbers, rad/m (broadcast together); no Nyquist rule is applied.
        depth : float
            Depth in m.
        quantity : {"stress", "strain"}
            Stress (Pa per Pa) or TENSOR strain (per Pa), by the Hooke's law of the layer at ``depth``.

        Returns
        -------
        ndarray, complex, shape ``(*broadcast(kx, ky).shape, 6, 3)``
            Rows: Voigt components ``(xx, yy, zz, yz, zx, xy)``; columns: loads ``(p, qx, qy)``. At
            ``k = 0`` the uniform solution (docs/theory.md section 6).
        """
        depth = check.depth(depth)
        E, nu = self.material_at(depth)
        kx = check.finite_array(kx, "kx", "rad/m")
        ky = check.finite_array(ky, "ky", "rad/m")
        T = transfer_matrix(self, kx, ky, depth)
        if quantity == "stress":
            return T
        if quantity == "strain":
            return np.einsum("ij,...jl->...il", compliance_matrix(E, nu), T)
        raise ValueError(f"quantity: must be 'stress' or 'strain', got {quantity!r}")

    def _amplitudes(self, k: np.ndarray, live: np.ndarray) -> dict[str, np.ndarray]:
        """Surface amplitudes on the wavenumbers ``k`` (one solve per distinct value), remembered for the
        last arrays asked (a contact grid asks the same bands once per compliance block) within
        :data:`AMPLITUDE_CACHE_BYTES`."""
        key = (k.shape, hashlib.blake2b(np.ascontiguousarray(k).tobytes(), digest_size=16).hexdigest())
        cache = self._amplitude_cache
        if key in cache:
            cache.move_to_end(key)
            return cache[key]
        amp = {name: np.zeros(k.shape, dtype=self._stack.dtype) for name in ("Wp", "Up", "Wq", "Uq", "V")}
        if live.any():
            unique, inverse = np.unique(k[live], return_inverse=True)
            for name, values in surface_amplitudes(unique, self._stack).items():
                amp[name][live] = values[inverse]
        cache[key] = amp
        while len(cache) > 1 and sum(a.nbytes for entry in cache.values() for a in entry.values()) > \
                AMPLITUDE_CACHE_BYTES:
            cache.popitem(last=False)
        return amp

    # -- fields ----------------------------------------------------------------------------------
    def stress(self, load, depth, points=None, components=None, tol: float = 1e-6, padding="auto"):
        """Stress (Pa, tension positive) at depth, as :meth:`HalfSpace.stress`.

        A periodic load is solved exactly (per wavenumber); an isolated one on a zero-padded periodic
        grid whose truncation error is estimated and kept below ``tol`` (see
        :func:`tactilab.forward.skin.layered_fields.layered_field`).

        Parameters
        ----------
        load : SurfaceLoad
            Tractions on the surface, Pa.
        depth : float or sequence of float
            Depths in m, within the layers on a rigid base.
        points : ndarray, shape (n, 2) or (n,), optional
            Sensor positions (x, y) in m; default the load grid. Off the nodes the exact trigonometric
            interpolant is summed there; an isolated load's sensors must lie within its grid.
        components : sequence of str, optional
            Voigt names; default all six.
        tol : float
            Requested error relative to the field's peak (the padding of an isolated load).
        padding : "auto" or int
            Isolated loads: the padded grid is ``padding`` times the load grid per axis.

        Returns
        -------
        FieldResult
            As the half-space's; ``method`` is ``"layered-periodic"`` or ``"layered-padded"``.
        """
        from .layered_fields import layered_field

        return layered_field(self, load, depth, points, components, tol, padding, "stress")

    def strain(self, load, depth, points=None, components=None, tol: float = 1e-6, padding="auto"):
        """Strain (TENSOR shear) at depth, from the stress by each layer's Hooke's law; see :meth:`stress`."""
        from .layered_fields import layered_field

        return layered_field(self, load, depth, points, components, tol, padding, "strain")

    def operator(self, shape, spacing, sensors=None, depth: float = 1e-3, components=("zz",), loads=("p",),
                 quantity: str = "stress", periodic: bool = False, padding: int = 4):
        """The load-to-sensor map at one depth as a ``scipy.sparse.linalg.LinearOperator`` with its adjoint.

        See :class:`tactilab.forward.skin.layered_operator.LayeredOperator`.
        """
        from .layered_operator import LayeredOperator

        return LayeredOperator(self, shape, spacing, sensors=sensors, depth=depth, components=components, loads=loads,
                               quantity=quantity, periodic=periodic, padding=padding)
