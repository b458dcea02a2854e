"""Build the procedure a protocol names, from the registry (:mod:`.registry`).

The registry imports a built-in procedure's module the first time a protocol names it, so
building a staircase loads neither psi nor the modelling room.
"""

from __future__ import annotations

from typing import Any

from .base import Procedure
from .registry import procedure_factory

__all__ = ["make_procedure"]


def make_procedure(config: Any, guess_rate: float = 0.0) -> Procedure:
    """Build the procedure that a protocol's ``procedure`` table describes.

    Parameters
    ----------
    config : ProcedureConfigBase
        A validated procedure configuration; ``config.method`` names a registered procedure.
    guess_rate : float
        The task's chance rate (0.5 for forced choice), passed to the procedure's factory.

    Raises
    ------
    UnregisteredError
        If the method, or a psi protocol's likelihood, is not registered.
    """
    procedure = procedure_factory(config)(config, guess_rate=guess_rate)
    if not isinstance(procedure, Procedure):
        raise TypeError(
            f"factory: the factory registered for {config.method!r} returned {type(procedure).__name__}, "
            "not a tactilab.experiments.procedures.Procedure; return a Procedure subclass instance"
        )
    return procedure
