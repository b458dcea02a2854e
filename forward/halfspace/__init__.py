"""The elastic half-space solver: surface tractions to stress and strain at depth.

This package is the solver's one door. Scene, display and synthesis code in
:mod:`tactilab.forward` imports from here, never from the modules inside (a test enforces it).
The theory is in ``docs/theory.md``.
"""

from . import _validation as validation
from ._validation import positive
from .adjoint import dottest
from .dcfft import dcfft_convolve, dcfft_correlate, dcfft_kernel_spectrum, dcfft_stress, padded_shape
from .facade import AccuracyWarning, FieldResult, HalfSpace
from .fields import (
    INVARIANTS,
    SHEAR_CONVENTION,
    compliance_matrix,
    invariants,
    output_weights,
    to_engineering,
)
from .kernels import (
    COMPONENTS,
    line_green,
    line_load_stress,
    point_green,
    point_load_stress,
)
from .loads import LOAD_COMPONENTS, SurfaceLoad
from .methods import METHODS, Method, select_method
from .operator import LoadToSensor
from .spectral import angular_wavenumbers, pressure_from_deflection, transfer

__all__ = [
    "AccuracyWarning",
    "COMPONENTS",
    "FieldResult",
    "HalfSpace",
    "INVARIANTS",
    "LOAD_COMPONENTS",
    "LoadToSensor",
    "METHODS",
    "Method",
    "SHEAR_CONVENTION",
    "SurfaceLoad",
    "angular_wavenumbers",
    "compliance_matrix",
    "dcfft_convolve",
    "dcfft_correlate",
    "dcfft_kernel_spectrum",
    "dcfft_stress",
    "dottest",
    "invariants",
    "line_green",
    "line_load_stress",
    "output_weights",
    "padded_shape",
    "point_green",
    "point_load_stress",
    "positive",
    "pressure_from_deflection",
    "select_method",
    "to_engineering",
    "transfer",
    "validation",
]
