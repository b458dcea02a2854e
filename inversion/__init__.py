"""tactilab.inversion: from sensor or receptor data back to the surface, with uncertainty.

Regularised inversion (:func:`invert_linear`), the exact Gaussian posterior
(:func:`gaussian_posterior`), MCMC over any model object (:func:`sample_posterior`, :class:`PosteriorModel`), over scene
parameters (:func:`sample_scene_posterior`) and
defect localisation. Import from here::

    from tactilab.inversion import invert_linear, gaussian_posterior, StationaryPrior
"""

from tactilab.core import attach, package_version

#: public name -> module that defines it
_EXPORTS = {
    "invert_linear": "linear",
    "LinearInversionResult": "linear",
    "invert_tv": "tv",
    "choose_lambda": "criteria",
    "CriteriaResult": "criteria",
    "plot_criteria": "criteria",
    "choose_lambda_iterative": "iterative_criteria",
    "StationaryPrior": "gaussian",
    "GaussianPosterior": "gaussian",
    "gaussian_posterior": "gaussian",
    "tikhonov_prior_spectrum": "gaussian",
    "MCMCResult": "mcmc",
    "DefectPosterior": "mcmc",
    "PosteriorModel": "sampler",
    "sample_posterior": "sampler",
    "mcmc_diagnostics": "sampler",
    "sample_scene_posterior": "mcmc",
    "invert_defect_position": "scene_inversion",
    "defect_profile": "scene_inversion",
    "check_scene_recording": "scene_check",
    "check_receptor_memory": "metamer_families",
    "check_max_steps": "chain_memory",
    "DefectScanModel": "scene_params",
    "defect_footprint": "scene_params",
    "Uniform": "priors",
    "Normal": "priors",
    "LogNormal": "priors",
    "LogUniform": "priors",
    "Beta1": "priors",
    "cramer_rao": "localisation",
    "localisation_study": "localisation",
    "halfspace_fourier_operator": "operators",
    "rigid_surface_height_operator": "operators",
    "FourierDiagonal": "operators",
    "halfspace_strain_operator": "strain_operators",
    "rigid_surface_height_strain_operator": "strain_operators",
    "plot_profile": "plots",
    "plot_corner": "plots",
    "StimulusFamily": "metamer_families",
    "SinusoidFamily": "metamer_families",
    "IndentationFamily": "metamer_grids",
    "GridLoadFamily": "metamer_grids",
    "TractorFamily": "metamer_families",
    "FamilyStimulus": "metamer_families",
    "metamer_pair": "metameres",
    "MetamerPair": "metameres",
    "PairScore": "metameres",
    "compare_stimuli": "metameres",
    "metamer_classes": "metameres",
    "MetamerClasses": "metameres",
    "resolvable_subspace": "metamer_spectra",
    "Subspace": "metamer_spectra",
    "metamer_ambiguity": "metamer_spectra",
    "Ambiguity": "metamer_spectra",
    "invert_many": "batch",
    "recording_keys": "batch",
    "metamer_scan": "metamer_batch",
    "invert_surface": "surface_scene",
    "scene_scan": "surface_scene",
    "invert_scan": "surface",
    "SurfacePosterior": "surface_posterior",
    "ContactScan": "surface_scan",
    "ProfileGrid": "surface_scan",
    "ScanJacobian": "surface_jacobian",
}

__version__ = package_version()
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS)
