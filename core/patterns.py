"""Regular expressions given by users, accepted only in a form that cannot backtrack badly.

A lab's ``--subject-pattern`` is a regular expression matched against a subject code. Python's
``re`` backtracks: ``(a+)+$`` or ``(a|a)*b`` takes exponential time on a code of 30 characters,
and no time limit can interrupt it. :func:`safe_pattern` accepts the patterns lab code schemes
need (``S[0-9]{3}``, ``(MRI|EEG)_?\\d{2,3}``) and refuses the constructions that make matching
slow: a repeated group (every repeat must apply to ONE character, a literal, ``.`` or a class),
back-references and look-arounds, and more than :data:`MAX_REPEATS` repeats of more than one
character. Matching a code of ``n`` characters then costs at most about ``n ** MAX_REPEATS``
steps, a few thousand for a 32-character BIDS label.
"""

from __future__ import annotations

import re
import re._constants as _c  # the parser's node names (stable within a Python version)
import re._parser as _parser  # the same parser re.compile uses: no second reading of the syntax

__all__ = ["MAX_PATTERN_LENGTH", "MAX_REPEATS", "safe_pattern"]

#: longest pattern accepted, characters
MAX_PATTERN_LENGTH = 200
#: most repeats (``*``, ``+``, ``{m,n}`` with n > 1) in one pattern
MAX_REPEATS = 4

_ONE_CHARACTER = {_c.LITERAL, _c.NOT_LITERAL, _c.ANY, _c.IN}
_REPEATS = {_c.MAX_REPEAT, _c.MIN_REPEAT, _c.POSSESSIVE_REPEAT}
_STRUCTURE = {_c.SUBPATTERN, _c.BRANCH, _c.AT, _c.ATOMIC_GROUP} | _ONE_CHARACTER | _REPEATS


def safe_pattern(pattern: str, name: str = "pattern") -> re.Pattern:
    """Compile ``pattern`` if it is valid and safe from catastrophic backtracking.

    Parameters
    ----------
    pattern : str
        A regular expression (Python syntax).
    name : str
        The argument or option that gave it (quoted first in messages).

    Returns
    -------
    re.Pattern

    Raises
    ------
    ValueError
        If it is not a string of at most :data:`MAX_PATTERN_LENGTH` characters, not a valid
        regular expression, repeats a group, uses a back-reference or look-around, or has
        more than :data:`MAX_REPEATS` repeats; the message says how to write it instead.
    """
    if not isinstance(pattern, str) or not 0 < len(pattern) <= MAX_PATTERN_LENGTH:
        raise ValueError(f"{name}: must be a regular expression of 1-{MAX_PATTERN_LENGTH} characters, got "
                         f"{str(pattern)[:80]!r}; e.g. 'S[0-9]{{3}}'")
    try:
        compiled = re.compile(pattern)
        tree = _parser.parse(pattern)
    except re.error as exc:
        raise ValueError(f"{name}: {pattern!r} is not a valid regular expression ({exc})") from None
    repeats = _walk(tree, pattern, name)
    if repeats > MAX_REPEATS:
        raise ValueError(f"{name}: {pattern!r} has {repeats} repeats (*, +, {{m,n}}); at most {MAX_REPEATS} keep "
                         "matching fast; write fixed counts, e.g. 'S[0-9]{3}'")
    return compiled


def _walk(items, pattern: str, name: str) -> int:
    """Check every node; return how many repeats of more than one character there are."""
    repeats = 0
    for op, argument in items:
        if op not in _STRUCTURE:
            raise ValueError(f"{name}: {pattern!r} uses {str(op).lower()} (a back-reference or look-around), "
                             "which can make matching slow; use letters, classes, groups and counted repeats")
        if op in _REPEATS:
            low, high, body = argument
            if len(body) != 1 or body[0][0] not in _ONE_CHARACTER:
                raise ValueError(f"{name}: {pattern!r} repeats a group, which can make matching take exponential "
                                 "time; repeat single characters or classes only, e.g. '(MRI|EEG)[0-9]{2,3}'")
            repeats += high > 1
        elif op == _c.SUBPATTERN:
            repeats += _walk(argument[-1], pattern, name)
        elif op == _c.ATOMIC_GROUP:
            repeats += _walk(argument, pattern, name)
        elif op == _c.BRANCH:
            repeats += sum(_walk(branch, pattern, name) for branch in argument[1])
    return repeats
