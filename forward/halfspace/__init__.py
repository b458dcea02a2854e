"""The elastic half-space solver: surface tractions to stress and strain at depth.

This package is the solver's one door. Scene, display and synthesis code in
:mod:`tactilab.forward` imports from here, never from the modules inside (a test enforces it).
The theory is in ``docs/theory.md``.
"""

from tactilab.core import attach
from tactilab.core import rules as validation  # noqa: F401 (public: the input rules, whose home is core)
from tactilab.core.rules import positive  # noqa: F401 (public)

#: public name -> module of the solver that defines it (loaded on first use, so that importing one
#: kernel does not load xarray through the facade)
_EXPORTS = {
    "AccuracyWarning": "facade",
    "angular_wavenumbers": "spectral",
    "compliance_matrix": "fields",
    "ContinuousLoad": "continuous",
    "COMPONENTS": "kernels",
    "dcfft_convolve": "dcfft",
    "dcfft_correlate": "dcfft",
    "dcfft_kernel_spectrum": "dcfft",
    "dcfft_stress": "dcfft",
    "DeflectionLoad": "continuous",
    "dottest": "adjoint",
    "FieldResult": "solve",
    "HalfSpace": "facade",
    "inverse_into": "_hotpath",  # transforms into given arrays: shared with the contact room
    "fft_first_inplace": "_hotpath",  # one axis' transforms into given arrays: the contact room's padded products
    "irfft_last_into": "_hotpath",
    "rfft_last_into": "_hotpath",
    "INVARIANTS": "fields",
    "invariants": "fields",
    "label": "fields",  # the labelled (xarray) field with cached coordinates, for skin models' results
    "largest_strain": "fields",
    "line_green": "kernels",
    "line_load_stress": "kernels",
    "LOAD_COMPONENTS": "loads",
    "LoadToSensor": "operator",
    "Method": "methods",
    "METHODS": "methods",
    "output_weights": "fields",
    "padded_shape": "dcfft",
    "pixel_influence": "surface_compliance",
    "point_geometry": "kernel_formulas",  # unchecked: for inner loops whose inputs are checked once
    "point_green": "kernels",
    "point_load_stress": "kernels",
    "point_unit": "kernel_formulas",  # unchecked: point_green's formula without its checks
    "pressure_from_deflection": "spectral",
    "rfftn_into": "_hotpath",
    "select_method": "methods",
    "SHEAR_CONVENTION": "fields",
    "surface_compliance": "surface_compliance",
    "SurfaceLoad": "loads",
    "to_engineering": "fields",
    "TractionField": "continuous",
    "transfer": "spectral",
}

__all__ = sorted([*_EXPORTS, "positive", "validation"])
__getattr__, __dir__ = attach(__name__, _EXPORTS)
