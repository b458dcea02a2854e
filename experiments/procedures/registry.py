"""Registries of procedures and likelihoods: protocol and session files name code, never import it.

A protocol's ``method`` names a procedure registered with :func:`register_procedure`; a psi
protocol's ``likelihood`` names a built-in psychometric family or a likelihood registered with
:func:`register_likelihood` from Python, or declared by an installed plug-in in the
``tactilab.likelihoods`` entry-point group. Nothing in a protocol or a session file is ever
turned into an import: names are looked up here, and an unknown name is refused with a message
that says how to register it.

The built-in procedures are named in :data:`BUILTIN_PROCEDURES` with the room door and class
of each (``constant_stimuli`` and ``staircase`` in :mod:`.staircase`, ``psi`` in :mod:`.psi`,
``model_discrimination`` in the modelling room, as it is built on the transduction models). The
class is fetched through its door the first time a protocol names its method; importing its
module registers it then. A staircase session thus never loads psi or the modelling room, and
the registry sits below every procedure without importing any.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from tactilab.core.plugins import installed_entry_point
from tactilab.data_schemas.experiment import check_name, register_procedure_config

__all__ = ["register_likelihood", "register_procedure", "get_likelihood", "registered_likelihoods",
           "registered_procedures", "procedure_factory", "ENTRY_POINT_GROUP", "BUILTIN_PROCEDURES",
           "UnregisteredError"]

#: Installed plug-ins declare custom likelihoods in this entry-point group (name -> callable).
ENTRY_POINT_GROUP = "tactilab.likelihoods"

Likelihood = Callable[..., Any]
_LIKELIHOODS: dict[str, Likelihood] = {}
_PROCEDURES: dict[str, tuple[type, Callable[..., Any]]] = {}
_RESERVED = ("weibull", "logistic", "normal_cdf", "gumbel")

#: built-in method -> (room door, class): touching the class through the door imports the module that
#: defines it, which registers the method (constants of this file, never data)
BUILTIN_PROCEDURES = {
    "constant_stimuli": ("tactilab.experiments.procedures", "ConstantStimuli"),
    "staircase": ("tactilab.experiments.procedures", "Staircase"),
    "psi": ("tactilab.experiments.procedures", "Psi"),
    "model_discrimination": ("tactilab.experiments.modelling", "ModelDiscrimination"),
}


class UnregisteredError(ValueError):
    """A protocol or session names a likelihood or procedure that is not registered here."""


def register_likelihood(name: str, f: Likelihood, *, replace: bool = False) -> None:
    """Register a custom psychometric likelihood under ``name``, for protocols and sessions.

    Parameters
    ----------
    name : str
        1-64 lower-case letters, digits or '_' (a protocol's ``likelihood = "name"``); the
        built-in family names are reserved.
    f : callable
        ``f(level, **params) -> p(positive)``, ``level`` of shape (n_levels, 1) in SI units of
        the varied parameter, each parameter grid of shape (1, n_theta); returns probabilities
        of shape (n_levels, n_theta).
    replace : bool
        Allow replacing another function registered under ``name``.

    Raises
    ------
    ValueError
        If the name breaks the rule, is a built-in family, is taken (and ``replace`` is False),
        or ``f`` is not callable.
    """
    check_name(name, "name", "likelihood")
    if name in _RESERVED:
        raise ValueError(f"name: {name!r} is a built-in psychometric family; choose another name")
    if not callable(f):
        raise ValueError(f"f: must be callable f(level, **params) -> p(positive), got {f!r}")
    if not replace and _LIKELIHOODS.get(name, f) is not f:
        raise ValueError(f"name: likelihood {name!r} is already registered; pass replace=True to replace it")
    _LIKELIHOODS[name] = f


def registered_likelihoods() -> list[str]:
    """Names registered from Python in this process (entry-point plug-ins load on first use)."""
    return sorted(_LIKELIHOODS)


def get_likelihood(name: str) -> Likelihood:
    """The custom likelihood registered as ``name`` (from Python, else from an installed plug-in).

    Only the entry point of that exact name in :data:`ENTRY_POINT_GROUP` is loaded, i.e. code
    an installed distribution declared; nothing named in a file is imported.

    Raises
    ------
    UnregisteredError
        If no likelihood of that name is registered; the message says how to register it.
    """
    check_name(name, "likelihood", "likelihood")
    if name not in _LIKELIHOODS:
        entry = installed_entry_point(ENTRY_POINT_GROUP, name)  # never a *.dist-info in the current folder
        if entry is not None:
            register_likelihood(name, entry.load())
    if name not in _LIKELIHOODS:
        raise UnregisteredError(
            f"likelihood: {name!r} is not registered in this process; register it from Python "
            f"first with tactilab.experiments.register_likelihood({name!r}, f) (then run, resume or "
            f"replay the session from Python), or install a plug-in that declares {name!r} in the "
            f"{ENTRY_POINT_GROUP!r} entry-point group"
        )
    return _LIKELIHOODS[name]


def register_procedure(name: str, config_cls: type, factory: Callable[..., Any], *,
                       replace: bool = False) -> None:
    """Register a procedure: protocols with ``method = name`` are validated by ``config_cls``
    and run by ``factory(config, guess_rate=...) -> Procedure``.

    Parameters
    ----------
    name : str
        The ``method`` protocols name (1-64 lower-case letters, digits or '_').
    config_cls : type
        A subclass of :class:`tactilab.data_schemas.experiment_procedures.ProcedureConfigBase`
        with ``method: Literal[name]``.
    factory : callable
        ``factory(config, *, guess_rate: float) -> Procedure`` (the task's chance rate is given);
        a factory with a ``display`` keyword also gets the session's display model
        (:func:`~.build.make_procedure`).
    replace : bool
        Allow replacing the factory of an already registered name.

    Raises
    ------
    ValueError
        If the name breaks the rule or is taken, ``config_cls`` is not a configuration class or
        ``factory`` is not callable.
    """
    check_name(name, "name", "procedure")
    _load_builtin(name)
    if not callable(factory):
        raise ValueError(f"factory: must be callable factory(config, guess_rate=...) -> Procedure, got {factory!r}")
    if not replace and name in _PROCEDURES and _PROCEDURES[name] != (config_cls, factory):
        raise ValueError(f"name: procedure {name!r} is already registered; pass replace=True to replace it")
    register_procedure_config(name, config_cls)
    _PROCEDURES[name] = (config_cls, factory)


def _load_builtin(name: str) -> None:
    """Load built-in procedure ``name`` once, through its room's door (its module registers it)."""
    if name in BUILTIN_PROCEDURES and name not in _PROCEDURES:
        door, cls = BUILTIN_PROCEDURES[name]
        getattr(importlib.import_module(door), cls)


def registered_procedures() -> list[str]:
    """The registered procedure names (the built-ins whether or not loaded yet)."""
    return sorted(set(_PROCEDURES) | set(BUILTIN_PROCEDURES))


def procedure_factory(config: Any) -> Callable[..., Any]:
    """The factory registered for ``config.method``.

    Raises
    ------
    UnregisteredError
        If no procedure of that name is registered, or ``config`` is not its configuration.
    """
    method = getattr(config, "method", None)
    if isinstance(method, str):
        _load_builtin(method)
    if method not in _PROCEDURES:
        raise UnregisteredError(
            f"config: procedure {method!r} is not registered (known: {registered_procedures()}); "
            "register it with tactilab.experiments.register_procedure(name, config_cls, factory)"
        )
    config_cls, factory = _PROCEDURES[method]
    if not isinstance(config, config_cls):
        raise UnregisteredError(
            f"config: procedure {method!r} takes a {config_cls.__name__}, got {type(config).__name__}"
        )
    return factory
