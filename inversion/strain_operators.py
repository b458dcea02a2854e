"""Strain versions of the inversion's Fourier operators: sensors and receptors record strain.

Strain is TENSOR strain (eps_ij; engineering shear gamma_ij = 2 eps_ij), dimensionless, the
convention of :mod:`tactilab.data_schemas.sensors` and of
:func:`tactilab.forward.halfspace.compliance_matrix`. A strain multiplier is the compliance row
of the component applied to the six stress multipliers of
:func:`~tactilab.inversion.operators.halfspace_fourier_operator`:

    eps_c(k) = sum_j S_cj sigma_j(k)          (S = compliance_matrix(E, nu), 1/Pa)

On a 1-D grid the load is uniform along y (plane strain, eps_yy = 0; the stress multipliers carry
sigma_yy = nu (sigma_xx + sigma_zz)).
"""

from __future__ import annotations

import numpy as np

from tactilab.forward.halfspace import compliance_matrix
from tactilab.core import rules

from .operators import FourierDiagonal, angular_wavenumbers, halfspace_fourier_operator

VOIGT = rules.COMPONENTS  # the one Voigt order

__all__ = ["halfspace_strain_operator", "rigid_surface_height_strain_operator"]


def _check_component(component: str) -> str:
    if component not in VOIGT:
        raise ValueError(f"component: expected a Voigt strain component from {VOIGT}, got {component!r}")
    return component


def _strain_multiplier(shape, spacing, depth: float, young_modulus: float, nu: float, load: str,
                       component: str) -> np.ndarray:
    row = compliance_matrix(young_modulus, nu)[VOIGT.index(_check_component(component))]
    out = np.zeros(tuple(shape), dtype=complex)
    for j, name in enumerate(VOIGT):
        if row[j] != 0.0:
            out = out + row[j] * halfspace_fourier_operator(tuple(shape), spacing, depth, nu, load, name).multiplier
    return out


def halfspace_strain_operator(shape, spacing, depth: float, young_modulus: float, nu: float = 0.5,
                              load: str = "p", component: str = "zz") -> FourierDiagonal:
    """FourierDiagonal map from one surface load component (Pa) to one tensor strain component.

    Parameters
    ----------
    shape : tuple of int
        ``(nx,)`` (plane strain) or ``(ny, nx)``, periodic grid, one sensor per node.
    spacing : float or (float, float)
        Grid spacing in m.
    depth : float
        Sensor depth in m.
    young_modulus : float
        E in Pa, > 0.
    nu : float
        Poisson's ratio in (-1, 0.5].
    load : {"p", "qx", "qy"}
        Load component the model holds (Pa).
    component : str
        Tensor strain component (Voigt name) the sensors record.

    Returns
    -------
    FourierDiagonal
        Strain per Pa of load.
    """
    young_modulus, nu = rules.young_modulus(young_modulus), rules.poisson_ratio(nu)
    return FourierDiagonal(_strain_multiplier(shape, spacing, depth, young_modulus, nu, load, component), spacing)


def rigid_surface_height_strain_operator(n: int, spacing: float, depth: float, young_modulus: float,
                                         poisson_ratio: float = 0.5, component: str = "zz") -> FourierDiagonal:
    """Plane strain: height ``H(x)`` (m) of a rigid surface in full frictionless contact -> tensor
    strain ``component`` at ``depth`` under every node (the strain twin of
    :func:`~tactilab.inversion.operators.rigid_surface_height_operator`).

    The height loads the skin with ``E |k| / (2 (1 - nu^2)) H(k)`` (docs/theory.md section 2);
    the strain is that pressure through :func:`halfspace_strain_operator`. The product does not
    depend on E (pressure scales with E, strain with 1/E). Closed forms for ``H0 cos kx``:
    ``eps_zz = -k H0 e^{-kZ} (1 - 2 nu + kZ) / (2 (1 - nu)) cos kx`` and
    ``eps_xx = -k H0 e^{-kZ} (1 - 2 nu - kZ) / (2 (1 - nu)) cos kx``. ``k = 0`` maps to 0.

    Parameters
    ----------
    n : int
        Grid nodes (periodic).
    spacing : float
        Grid spacing in m.
    depth : float
        Sensor depth in m, > 0.
    young_modulus : float
        E in Pa, > 0 (it cancels, but the pressure-strain pair is built through it).
    poisson_ratio : float
        nu in (-1, 0.5].
    component : str
        Tensor strain component (Voigt name).

    Returns
    -------
    FourierDiagonal
        Strain (dimensionless) per m of height.
    """
    spacing = rules.spacing(spacing, 1)[0]
    depth = rules.depth(depth)
    young_modulus = rules.young_modulus(young_modulus)
    poisson_ratio = rules.poisson_ratio(poisson_ratio, "poisson_ratio")
    (k,) = angular_wavenumbers((int(n),), spacing)
    p_to_strain = _strain_multiplier((int(n),), spacing, depth, young_modulus, poisson_ratio, "p", component)
    return FourierDiagonal(p_to_strain * young_modulus * np.abs(k) / (2 * (1 - poisson_ratio**2)), spacing)
