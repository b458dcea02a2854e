"""tactilab.core: the ground floor that every other part builds on, naming no touch concept.

It holds the input rules (one function per quantity), the unit parser, the face loader of every
part, the package version and the batch engine (independent tasks, serial or on Dask, resumable,
seeded by key). It imports no other part of tactilab (``tests/test_import_direction.py``
checks it). Use it through this face::

    from tactilab.core import rules, to_si
    rules.poisson_ratio(0.49)          # 0.49; 0.6 raises a ValueError naming the rule and the fix
    rules.components(["zz", "xz"])     # ('zz', 'zx'): one order, one alias table
"""

from .faces import attach
from .version import package_version

#: public name -> module that defines it
_EXPORTS = {
    "COMPONENTS": "rules",
    "COMPONENT_ALIASES": "rules",
    "to_si": "units",
    "SI_UNIT": "units",
    "UNITS": "units",
    "attach": "faces",
    "check_origin": "faces",
    "ShadowedInstallWarning": "faces",
    "package_version": "version",
    "BatchReport": "batch",
    "batch_client": "batch",
    "read_result": "batch",
    "result_path": "batch",
    "run_batch": "batch",
    "stable_hash": "batch",
    "task_rng": "batch",
    "write_netcdf_atomic": "batch",
    "write_netcdf": "netcdf",
    "cf_ready": "netcdf",
    "cf_problems": "netcdf",
}

__version__ = package_version()
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS)
