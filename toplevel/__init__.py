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
until one is imported.
"""

from tactilab.core.version import package_version

__version__ = package_version()
__all__ = ["__version__"]
