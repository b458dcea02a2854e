"""tactilab.demo: the end-to-end demonstration behind ``tactilab demo``.

Each module is one section of the report, in pipeline order (:data:`SECTIONS`); each has
``run_demo(report_dir, progress) -> Iterator[str]`` that writes its files and yields the lines
to print.
"""

from . import (analysis, contact, display, experiments, forward, inversion, metameres, records, scene_models, scenes,
               surface)

#: The report's sections in pipeline order.
SECTIONS = (records, forward, contact, scenes, scene_models, display, inversion, metameres, surface, experiments,
            analysis)

__all__ = ["SECTIONS"]
