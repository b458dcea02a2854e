"""The memory rule for emcee's chains: ``max_steps`` is a size the user gives, so the chains it would
grow to are estimated before sampling starts and refused above the limit, naming the step count that
fits (:func:`tactilab.core.memory.check_count`)."""

from __future__ import annotations

from tactilab.core.memory import check_count

__all__ = ["check_max_steps", "default_walkers"]


def default_walkers(n_params: int) -> int:
    """Walkers per ensemble when none are given: max(16, 4 P), made even."""
    n = max(16, 4 * int(n_params))
    return n + n % 2


def check_max_steps(max_steps: int, n_params: int, *, n_ensembles: int = 4, n_walkers: int | None = None,
                    name: str = "max_steps") -> int:
    """The memory rule for emcee's chains: ``max_steps`` steps of every walker, kept and copied once for
    the convergence checks, must fit the limit (:data:`tactilab.core.memory.MEMORY_LIMIT_BYTES`).

    Parameters
    ----------
    max_steps : int
        Step limit per ensemble.
    n_params : int
        Sampled parameters P.
    n_ensembles, n_walkers : int
        As :func:`sample_posterior` (``n_walkers`` None: :func:`default_walkers`).
    name : str
        The argument that set ``max_steps`` (``--max-steps`` on the command line).

    Raises
    ------
    ValueError
        Above the limit, naming the largest step count that fits.
    """
    walkers = default_walkers(n_params) if n_walkers is None else int(n_walkers)
    per_step = 2 * 8 * int(n_ensembles) * walkers * (int(n_params) + 2)  # chain, log-prob, acceptance; one copy
    return check_count(max_steps, per_step, name, f"steps ({int(n_ensembles)} ensembles x {walkers} walkers x "
                                                  f"{int(n_params)} parameters, {per_step} bytes per step)")
