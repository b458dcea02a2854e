"""The memory rule: an array sized by numbers read from a file or an option is checked before
it is allocated, so a typo (``frame_rate_hz = "1e9Hz"``) is one line, not gigabytes and a crash.

:func:`check_memory` names the argument, the size it would need, the limit and the fix;
:func:`check_count` does it for a size given as a count (receptors, frames, steps, pairs) and names
the largest count that fits. The limit
is :data:`MEMORY_LIMIT_BYTES` (1 GiB per array: far above any stimulus or recording tactilab
plans, far below a lab machine's memory).
"""

from __future__ import annotations

__all__ = ["MEMORY_LIMIT_BYTES", "check_count", "check_memory"]

#: the largest array (bytes) tactilab allocates from a size it was given
MEMORY_LIMIT_BYTES = 2**30


def check_memory(n_bytes: int | float, name: str, what: str, fix: str,
                 limit_bytes: int = MEMORY_LIMIT_BYTES) -> int:
    """Return ``n_bytes`` (as an int) if it is within ``limit_bytes``.

    Parameters
    ----------
    n_bytes : int or float
        Size the allocation would need, bytes.
    name : str
        The argument that set the size (quoted first in the message).
    what : str
        What would be allocated, e.g. ``"the drive (12000000 frames x 10 tractors)"``.
    fix : str
        How to bring the size down.
    limit_bytes : int
        The limit, bytes.

    Raises
    ------
    ValueError
        If ``n_bytes`` is not finite or exceeds ``limit_bytes``.
    """
    size = float(n_bytes)
    if not size <= limit_bytes:  # also refuses NaN
        raise ValueError(f"{name}: {what} would need {size / 2**30:.3g} GiB, more than the "
                         f"{limit_bytes / 2**30:.3g} GiB limit for one array; {fix}")
    return int(size)


def check_count(count: int | float, bytes_per_item: int | float, name: str, what: str, fix: str = "",
                limit_bytes: int = MEMORY_LIMIT_BYTES) -> int:
    """Return ``count`` (as an int) if ``count`` items of ``bytes_per_item`` fit in ``limit_bytes``.

    Parameters
    ----------
    count : int or float
        The size the user gave (receptors, frames, steps, ...).
    bytes_per_item : int or float
        Bytes the allocation needs per item (every array of that length alive at once), > 0.
    name : str
        The argument that set ``count`` (quoted first in the message).
    what : str
        What would be allocated per item, e.g. ``"readout matrices (2 depths x 10 tractors per receptor)"``.
    fix : str
        Another way to bring the size down (appended after the largest count that fits).
    limit_bytes : int
        The limit, bytes.

    Raises
    ------
    ValueError
        ``"<name>: <count> x <what> would need <GiB>, more than the <limit> GiB limit for one array;
        give <name> at most <largest>[; <fix>]"``.
    """
    largest = int(limit_bytes // float(bytes_per_item))
    tell = f"give {name} at most {largest}" + (f"; {fix}" if fix else "")
    check_memory(float(count) * float(bytes_per_item), name, f"{count:g} {what}" if isinstance(count, float)
                 else f"{count} {what}", tell, limit_bytes)
    return int(count)
