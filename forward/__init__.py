"""tactilab.forward: skin mechanics, from surface tractions to strain and stress at receptor depth.

The elastic half-space solver (:class:`HalfSpace`, :class:`SurfaceLoad`, the operator and the
kernels) lives in :mod:`tactilab.forward.halfspace`; the contact engine (:func:`solve_contact`,
the frictional contact of the skin with a rigid surface, and the Hertz closed forms) in
:mod:`tactilab.forward.contact`; touch scenes (contacts, surfaces, the biomimetic finger),
tractor displays and tactile synthesis are built on them. Import from here::

    from tactilab.forward import HalfSpace, SurfaceLoad, HertzContact, solve_contact
"""

from tactilab.core import attach, package_version

#: public name -> module that defines it
_EXPORTS = {
    # the solver (its own door)
    "HalfSpace": "halfspace",
    "SurfaceLoad": "halfspace",
    "FieldResult": "halfspace",
    "AccuracyWarning": "halfspace",
    "LoadToSensor": "halfspace",
    "METHODS": "halfspace",
    "COMPONENTS": "halfspace",
    "LOAD_COMPONENTS": "halfspace",
    "SHEAR_CONVENTION": "halfspace",
    "point_green": "halfspace",
    "transfer": "halfspace",
    "line_green": "halfspace",
    "point_load_stress": "halfspace",
    "line_load_stress": "halfspace",
    "pressure_from_deflection": "halfspace",
    "angular_wavenumbers": "halfspace",
    "dottest": "halfspace",
    "dcfft_stress": "halfspace",
    "to_engineering": "halfspace",
    "invariants": "halfspace",
    "ReceptorHypothesis": "receptors",
    # skin models beyond the half-space (their own door)
    "Layer": "skin",
    "LayeredHalfSpace": "skin",
    # contacts and surfaces
    "solve_contact": "contact",
    "ContactSolution": "contact",
    "ContactCompliance": "contact",
    "solve_tangential": "contact",
    "TangentialSolution": "contact",
    "HertzContact": "contact",
    "interfacial_traction": "contact",
    "stick_radius": "contact",
    "ContactLoad": "contact",
    "WestergaardContact": "contact",
    "PeriodicFlatPunch": "contact",
    "harmonic_field": "contact",
    "interface_model_errors": "contact",
    "linear_pressure": "contact",
    "modulation_pressure": "contact",
    "full_contact_pressure": "contact",
    "ContinuousLoad": "halfspace",
    # skin models with time (viscoelastic)
    "Prony": "skin",
    "ViscoelasticHalfSpace": "skin",
    "solve_viscoelastic_contact": "skin",
    "skin_from_material": "skin",
    "TractionField": "halfspace",
    "DeflectionLoad": "halfspace",
    "Surface": "surfaces",
    "Feature": "surfaces",
    "RecordFeature": "surfaces",
    "RandomSquareWaveGrating": "surfaces",
    "rigid_surface_pressure": "surfaces",
    "random_rough_surface": "surfaces",
    "write_contact": "contact_files",
    "plot_contact_pressure": "contact_files",
    "plot_stick_slip": "contact_files",
    # the biomimetic finger and scans
    "BiomimeticFinger": "finger",
    "Fingerprint": "finger",
    "scan_recording": "scanning",
    "scene_finger": "scanning",
    "scene_recording": "scanning",
    "scanned_surface": "scanning",
    "simulate_scene": "scene_simulation",
    "solve_scan": "scene_contact",
    "ScanSolution": "scene_contact",
    "finger_gap": "scene_contact",
    "SensorReadout": "scene_readout",
    "SceneFrames": "scene_frames",
    "run_model": "scene_models",
    "choose_model": "scene_models",
    "scene_signals": "scene_models",
    "signal_error": "scene_models",
    "read_load": "load_files",
    "write_field": "load_files",
    "plot_field": "plots",
    "wiener_kernel": "exploration",
    # the founding papers' studies through the solved contact (bench_scene_studies, the demo)
    "defect_response": "scene_studies",
    "receptive_field_change": "scene_studies",
    "superposition_error": "scene_studies",
    "fingerprint_band_pass": "scene_studies",
    "wiener_kernels": "scene_studies",
    "kernel_error": "scene_studies",
    "linear_kernel": "exploration",
    "shape_invariance": "exploration",
    "kernel_identification": "exploration",
    "texture_spectrum": "exploration",
    "plot_fingerprint_spectra": "finger_plots",
    "plot_wiener_kernels": "finger_plots",
    # tractors, displays and synthesis
    "sliding_sinusoid_strain": "tractors",
    "tractor_row_strain": "tractors",
    "pair_phi_psi": "tractors",
    "array_phi_psi": "tractors",
    "travelling_wave_drive": "tractor_display",
    "display_row_strain": "tractor_display",
    "render_virtual_surface": "tractor_display",
    "display_patch_strain_3d": "tractor_display",
    "display_scene_outputs": "display_scene",
    "optimal_half_spacing": "synthesis",
    "matching_line_load": "synthesis",
    "matching_traction_amplitude": "synthesis",
    "max_virtual_amplitude": "synthesis",
    "design_table": "synthesis",
    "depth_scaling": "synthesis",
}

__version__ = package_version()
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS)
