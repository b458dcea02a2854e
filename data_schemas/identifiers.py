"""The identifiers a protocol or a session carries, each with its one rule: BIDS labels
(:func:`check_label`), pseudonymous subject codes (:func:`check_subject`) and registered names
(:func:`check_name`: a likelihood family, a procedure method; never an import path).

Labels and subject codes go into file names and exports; registered names select code that was
registered from Python. A file holds data only, so nothing here is ever imported or evaluated.
"""

from __future__ import annotations

import re
from typing import Any

from tactilab.core.patterns import safe_pattern

_LABEL = re.compile(r"[A-Za-z0-9]{1,32}")  # fullmatch: "$" would let a final newline through
#: A registered name (likelihood family, custom likelihood, procedure method): never a path.
NAME_RULE = re.compile(r"^[a-z][a-z0-9_]{0,63}$")


def check_label(value: str, name: str) -> str:
    """Return ``value`` if it is a BIDS label (1-32 letters or digits); ``name`` is quoted in the error.

    Subject and session labels go into file names and exports, so a real name (with a space)
    is refused: pseudonymous codes only.
    """
    if not isinstance(value, str) or not _LABEL.fullmatch(value):
        raise ValueError(
            f"{name}: must be 1-32 letters or digits (a BIDS label; a pseudonymous code, never "
            f"a name), got {value!r}; use e.g. 'S01'"
        )
    return value


_DATE_RUN = re.compile(r"\d{6,8}")
_NAME_LIKE = re.compile(r"^(?:[A-Z][a-z]{1,}){2,}\d*$")


def _looks_like_date(digits: str) -> bool:
    """``digits`` (6 or 8 digits) reads as YYYYMMDD, DDMMYYYY, YYMMDD or DDMMYY."""
    import datetime as _dt

    formats = ("%Y%m%d", "%d%m%Y", "%m%d%Y") if len(digits) == 8 else ("%y%m%d", "%d%m%y", "%m%d%y")
    for fmt in formats:
        try:
            _dt.datetime.strptime(digits, fmt)
            return True
        except ValueError:
            continue
    return False


def check_subject(value: str, name: str = "subject", pattern: str | None = None) -> str:
    """Return ``value`` if it is a pseudonymous subject code.

    Rule: a BIDS label (1-32 letters or digits, :func:`check_label`) that does not look like a
    person: no run of 6 or 8 digits that reads as a date (``19850412``, ``120485``) and not two
    or more capitalised words (``JaneDoe``, ``JaneDoe19850412``). A lab with its own code scheme
    passes ``pattern`` (a regular expression the whole code must match, e.g. ``"S[0-9]{3}"``);
    the name and date heuristics are then replaced by it.
    """
    check_label(value, name)
    if pattern is not None:
        matched = safe_pattern(pattern, "subject pattern").fullmatch(value) is not None  # no slow backtracking
        if not matched:
            raise ValueError(f"{name}: {value!r} does not match the lab's subject pattern {pattern!r}; use a code of "
                             "that form")
        return value
    runs = [run for run in _DATE_RUN.findall(value) if len(run) in (6, 8)]
    if any(_looks_like_date(run) for run in runs) or _NAME_LIKE.match(value):
        raise ValueError(
            f"{name}: {value!r} looks like a name or a date of birth; subject codes are pseudonymous "
            "(e.g. 'S01'); a lab with its own scheme gives its pattern (--subject-pattern)"
        )
    return value


def check_name(value: Any, name: str, what: str) -> str:
    """Return ``value`` if it is a registered-name string (lower-case letters, digits, '_').

    Import paths (``"package.module:function"``), file paths and anything else are refused:
    protocol and session files are data and never name code.
    """
    if not isinstance(value, str) or not NAME_RULE.fullmatch(value):
        raise ValueError(
            f"{name}: must be the name of a registered {what} (1-64 lower-case letters, digits or "
            f"'_', starting with a letter), got {value!r}; a protocol names registered code, it never "
            "holds an import path (register custom code from Python, see docs/experiments.md)"
        )
    return value
