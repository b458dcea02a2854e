"""tactilab: touch science, from skin mechanics to psychophysics.

The parts, each with its own face (import from these)::

    tactilab.core          ground floor: input rules, units, faces, version
    tactilab.data_schemas  validated records and file I/O
    tactilab.forward       the elastic half-space model and scenes
    tactilab.inversion     Bayesian inversion of sensor data
    tactilab.experiments   psychophysics sessions and devices
    tactilab.demo          the runnable tour
    tactilab.cli           the ``tactilab`` command

This package is regular (it has this file) so that a folder named ``tactilab`` in the current
directory, such as a fresh clone, does not take the installed package's place. It loads no part
until one is imported, and reads ``__version__`` from the installed metadata on first use (so that
``tactilab --help`` does not pay for it).
"""

__all__ = ["__version__"]


def __getattr__(name: str) -> str:
    """``__version__``, from the distribution's metadata (:func:`tactilab.core.package_version`)."""
    if name == "__version__":
        from tactilab.core.version import package_version

        return package_version()
    raise AttributeError(f"module 'tactilab' has no attribute {name!r}")
