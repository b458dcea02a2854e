"""Build the procedure a protocol names, from the registry (:mod:`.registry`).

The registry imports a built-in procedure's module the first time a protocol names it, so
building a staircase loads neither psi nor the modelling room.
"""

from __future__ import annotations

import inspect
from typing import Any

from .base import Procedure
from .registry import procedure_factory

__all__ = ["make_procedure"]


def make_procedure(config: Any, guess_rate: float = 0.0, *, display: Any = None, finger: Any = None) -> Procedure:
    """Build the procedure that a protocol's ``procedure`` table describes.

    Parameters
    ----------
    config : ProcedureConfigBase
        A validated procedure configuration; ``config.method`` names a registered procedure.
    guess_rate : float
        The task's chance rate (0.5 for forced choice), passed to the procedure's factory.
    display : SimulatedDisplay, optional
        A model of the session's display (what it renders, limits included). Passed to the
        factories that take a ``display`` keyword (the model-discrimination design predicts from
        the stimulus the display renders); factories without one build as before.
    finger : FingerConfig, optional
        The finger that presses the protocol's physical gratings (its ``[finger]`` table), passed to
        the factories that take a ``finger`` keyword (the design then predicts through the solved
        contact of that finger, ``TransductionModel(source="contact")``).

    Raises
    ------
    UnregisteredError
        If the method, or a psi protocol's likelihood, is not registered.
    """
    factory = procedure_factory(config)
    extra = {name: value for name, value in (("display", display), ("finger", finger))
             if value is not None and _takes(factory, name)}
    procedure = factory(config, guess_rate=guess_rate, **extra)
    if not isinstance(procedure, Procedure):
        raise TypeError(
            f"factory: the factory registered for {config.method!r} returned {type(procedure).__name__}, "
            "not a tactilab.experiments.procedures.Procedure; return a Procedure subclass instance"
        )
    return procedure


def _takes(factory, keyword: str) -> bool:
    try:
        parameters = inspect.signature(factory).parameters
    except (TypeError, ValueError):  # a builtin without a signature: it takes only what the registry documents
        return False
    return keyword in parameters
