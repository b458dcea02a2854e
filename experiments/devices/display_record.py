"""A session's record of its display description: the JSON data, its hash, and how two differ."""

from __future__ import annotations

import hashlib
import json

from tactilab.data_schemas.display import LINK_FIELDS

__all__ = ["description_record", "description_differences"]


def description_record(description) -> tuple[dict, str]:
    """The full display description as JSON data and its SHA-256 (hex) over canonical JSON.

    A session records both, so that a resume on a display with other limits is refused. The link
    fields (``pairing_key_file``, ``lookahead_s``) are left out while they hold their defaults, so
    that a description recorded before they existed still matches.
    """
    data = description.model_dump(mode="json")
    for name, default in LINK_FIELDS.items():
        if data.get(name, default) == default:
            data.pop(name, None)
    canonical = json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return data, hashlib.sha256(canonical.encode()).hexdigest()


def description_differences(recorded: dict, given: dict) -> list[str]:
    """``"field: recorded X, given Y"`` for every field that differs between two descriptions."""
    return [f"{key}: recorded {recorded.get(key)!r}, given {given.get(key)!r}"
            for key in sorted(set(recorded) | set(given)) if recorded.get(key) != given.get(key)]
