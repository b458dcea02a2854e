"""Receptor hypotheses: which strain readouts a population of receptors makes, and where.

A :class:`ReceptorHypothesis` says which strain components (or invariants) receptors read, at
which depths, with which shear convention and noise. It turns a strain field at depth into the
readout vector that metamer analysis (``tactilab.inversion``) and model comparison use.

Conventions (docs/theory.md section 1):

- input strain is the symmetric TENSOR strain in Voigt order (xx, yy, zz, yz, zx, xy);
- with ``shear="engineering"`` the shear readouts ``yz, zx, xy`` are ``gamma_ij = 2 eps_ij``, and
  the shear-type invariants ``max_shear`` and ``octahedral`` are doubled likewise; ``von_mises``
  (``sqrt(2/3 e:e)``, ``e`` the deviatoric tensor) and ``deviatoric_norm`` (``sqrt(e:e)``) are
  tensor norms and do not depend on the convention;
- the readout vector is ordered (depth, component, receptor) in C order:
  ``n_readouts = n_depths * n_components * n_receptors``.

The string form (``"xx,zx@1.25mm"``, ``"max_shear@1mm,2mm:engineering"``) is the grammar of
:mod:`tactilab.data_schemas.hypothesis`; ``ReceptorHypothesis.parse(str(h)) == h``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from tactilab.core.rules import COMPONENTS
from tactilab.data_schemas.hypothesis import (
    LINEAR_COMPONENTS,
    SHEAR_CONVENTIONS,
    check_components,
    check_depth,
    check_noise,
    format_hypothesis,
    parse_hypothesis,
)

#: Voigt order of the strain components (the one order, tactilab.core.rules.COMPONENTS)
VOIGT = COMPONENTS
_SHEAR = ("yz", "zx", "xy")
_PAIRS = {"xx": (0, 0), "yy": (1, 1), "zz": (2, 2), "yz": (1, 2), "zx": (2, 0), "xy": (0, 1)}


@dataclass(frozen=True)
class ReceptorHypothesis:
    """Which strain readouts receptors make, at which depths.

    Parameters
    ----------
    components : tuple of str
        Linear: the Voigt names ``COMPONENTS`` (xx, yy, zz, yz, zx, xy; aliases ``"xz"``, ``"zy"``, ``"yx"``
        accepted and stored canonically) and ``"volumetric"`` (``tr eps``); nonlinear:
        ``"max_shear"``, ``"von_mises"``, ``"octahedral"``, ``"deviatoric_norm"``.
    depths : tuple of float
        Receptor depths, m, each finite and > 0.
    noise_std : float or None
        Standard deviation of one reading, in the readout's units (strain, dimensionless);
        None when no noise model is stated.
    shear : {"tensor", "engineering"}
        Shear readouts as tensor ``eps_ij`` or engineering ``gamma_ij = 2 eps_ij``.

    Raises
    ------
    ValueError
        For an unknown or repeated component, a depth <= 0, noise <= 0 or an unknown convention.
    """

    components: tuple[str, ...]
    depths: tuple[float, ...]
    noise_std: float | None = None
    shear: Literal["tensor", "engineering"] = "tensor"

    def __post_init__(self) -> None:
        object.__setattr__(self, "components", check_components(self.components))
        depths = (self.depths,) if np.ndim(self.depths) == 0 else tuple(self.depths)
        if not depths:
            raise ValueError("depths: give at least one receptor depth in m, e.g. (1.25e-3,)")
        object.__setattr__(self, "depths", tuple(check_depth(d) for d in depths))
        object.__setattr__(self, "noise_std", check_noise(self.noise_std))
        if self.shear not in SHEAR_CONVENTIONS:
            raise ValueError(f"shear: must be 'tensor' or 'engineering', got {self.shear!r}")

    # ----- shape ------------------------------------------------------------------------
    @property
    def linear(self) -> bool:
        """True when every readout is a linear function of strain (no invariant)."""
        return all(c in LINEAR_COMPONENTS for c in self.components)

    @property
    def n_components(self) -> int:
        """Number of readout components."""
        return len(self.components)

    @property
    def n_depths(self) -> int:
        """Number of receptor depths."""
        return len(self.depths)

    def n_readouts(self, n_receptors: int) -> int:
        """``n_depths * n_components * n_receptors``."""
        return self.n_depths * self.n_components * int(n_receptors)

    def with_noise(self, noise_std: float | None) -> ReceptorHypothesis:
        """The same hypothesis with another noise level."""
        return ReceptorHypothesis(self.components, self.depths, noise_std, self.shear)

    # ----- readouts ---------------------------------------------------------------------
    def weights(self) -> np.ndarray:
        """Rows mapping tensor Voigt strain to the readouts, shape (n_components, 6).

        Shear rows carry 2 under the engineering convention; ``volumetric`` is (1, 1, 1, 0, 0, 0).

        Raises
        ------
        ValueError
            If a component is a nonlinear invariant (no weight matrix exists).
        """
        if not self.linear:
            bad = [c for c in self.components if c not in LINEAR_COMPONENTS]
            raise ValueError(f"weights: the invariants {bad} are nonlinear in strain and have no weight rows; "
                             f"use readout(strain), or linear components {LINEAR_COMPONENTS}")
        w = np.zeros((self.n_components, 6))
        scale = 2.0 if self.shear == "engineering" else 1.0
        for i, c in enumerate(self.components):
            if c == "volumetric":
                w[i, :3] = 1.0
            else:
                w[i, VOIGT.index(c)] = scale if c in _SHEAR else 1.0
        return w

    def readout(self, strain: ArrayLike) -> np.ndarray:
        """Readout vectors of strain fields at the hypothesis's depths.

        Parameters
        ----------
        strain : array_like, shape (n_depths, ..., n_receptors, 6)
            TENSOR Voigt strain at each depth (in ``depths`` order) and receptor; the middle
            axes (e.g. time frames) are kept.

        Returns
        -------
        ndarray, shape (..., n_readouts)
            Ordered (depth, component, receptor) in C order.
        """
        s = np.asarray(strain, dtype=float)
        if s.ndim < 3 or s.shape[0] != self.n_depths or s.shape[-1] != 6:
            raise ValueError(f"strain: expected shape (n_depths={self.n_depths}, ..., n_receptors, 6) of tensor "
                             f"Voigt strain, got {s.shape}")
        if not np.isfinite(s).all():
            raise ValueError("strain: must be finite (no NaN or inf)")
        if self.linear:
            r = s @ self.weights().T  # (n_depths, ..., n_receptors, n_components)
        else:
            r = np.stack([self._component(s, c) for c in self.components], axis=-1)
        r = np.moveaxis(r, 0, -3)  # (..., n_depths, n_receptors, n_components)
        r = np.swapaxes(r, -1, -2)  # (..., n_depths, n_components, n_receptors)
        return r.reshape(*r.shape[:-3], -1)

    def _component(self, s: np.ndarray, name: str) -> np.ndarray:
        scale = 2.0 if self.shear == "engineering" else 1.0
        if name in LINEAR_COMPONENTS:
            if name == "volumetric":
                return s[..., 0] + s[..., 1] + s[..., 2]
            return s[..., VOIGT.index(name)] * (scale if name in _SHEAR else 1.0)
        t = np.empty(s.shape[:-1] + (3, 3))
        for k, c in enumerate(VOIGT):
            i, j = _PAIRS[c]
            t[..., i, j] = s[..., k]
            t[..., j, i] = s[..., k]
        trace = np.trace(t, axis1=-2, axis2=-1)
        dev = t - trace[..., None, None] / 3.0 * np.eye(3)
        dd = np.einsum("...ij,...ij->...", dev, dev)
        if name == "von_mises":
            return np.sqrt(2.0 / 3.0 * dd)
        if name == "deviatoric_norm":
            return np.sqrt(dd)
        if name == "octahedral":
            return scale * np.sqrt(dd / 3.0)
        principal = np.linalg.eigvalsh(t)
        return scale * 0.5 * (principal[..., -1] - principal[..., 0])  # max_shear

    # ----- text form ----------------------------------------------------------------------
    @classmethod
    def parse(cls, text: str) -> ReceptorHypothesis:
        """Read ``components@depths[:shear][;noise=VALUE]`` (see :mod:`tactilab.data_schemas.hypothesis`).

        Examples: ``"zx@1mm"``, ``"xx,zx@1mm,2mm"``, ``"max_shear@1.25mm:engineering"``.
        """
        spec = parse_hypothesis(text)
        return cls(spec.components, spec.depths_m, spec.noise_std, spec.shear)  # type: ignore[arg-type]

    def __str__(self) -> str:
        return format_hypothesis(self.components, self.depths, self.shear, self.noise_std)
