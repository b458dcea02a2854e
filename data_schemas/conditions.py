"""A conditions table: constant stimuli over several stimulus fields at once (a pitch x amplitude design).

A protocol's ``[procedure]`` of ``method = "constant_stimuli"`` may name a CSV file instead of
``levels``, laid out as PsychoPy's conditions files are: one row per condition, one column per
stimulus field, the unit in each header::

    pitch [mm],amplitude [um]
    2,3
    2,6
    4,3
    4,6

Columns: ``amplitude``, ``pitch``, ``speed``, ``duration``, ``ramp`` and ``frame_rate`` (each with
its unit in brackets: ``[um]``, ``[mm]``, ``[mm/s]``, ``[ms]``, ``[Hz]``, ...) and ``surface``
(``sinusoid`` or ``square``, no unit). The file is read when the protocol is loaded
(:meth:`Protocol.from_toml`): resolved against the protocol's folder, it must lie inside that
folder, be a regular file and not a symlink. Its rows are kept in the protocol in SI (a session
records them, so a session never depends on the file again).
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path
from typing import Any

from .paths import file_inside
from .units import to_si

#: header name -> (stimulus field, dimension; "text" for the waveform)
COLUMNS = {"amplitude": ("amplitude_m", "length"), "pitch": ("pitch_m", "length"),
           "speed": ("speed_m_per_s", "speed"), "duration": ("duration_s", "time"),
           "ramp": ("ramp_s", "time"), "frame_rate": ("frame_rate_hz", "frequency"), "surface": ("surface", "text")}
#: stimulus field -> dimension (rows given inline, in SI or with units)
FIELDS = dict(COLUMNS.values())
MAX_CONDITIONS = 1000
MAX_CONDITIONS_BYTES = 1_000_000
_EXAMPLE_UNIT = {"length": "mm", "speed": "mm/s", "time": "ms", "frequency": "Hz"}
_HEADER = re.compile(r"\s*([a-z_]+)\s*(?:\[\s*([^\]]+?)\s*\])?\s*")


def conditions_path(folder: str | Path, name: str) -> Path:
    """``folder / name``, checked by :func:`.paths.file_inside` (the conditions CSV next to a protocol)."""
    return file_inside(folder, name, key="procedure.conditions", owner="protocol", what="CSV")


def read_conditions(folder: str | Path, name: str) -> list[dict[str, Any]]:
    """The rows of the conditions CSV ``name`` (see :func:`conditions_path`), as stimulus fields in SI.

    Raises
    ------
    ValueError
        A bad path, a file above 1 MB or not UTF-8 text, a header without a unit (or with one on
        ``surface``), an unknown or repeated column, an empty or unparsable cell, no rows, more
        than :data:`MAX_CONDITIONS` rows, or two rows that give the same condition.
    """
    path = conditions_path(folder, name)
    if path.stat().st_size > MAX_CONDITIONS_BYTES:
        raise ValueError(f"procedure.conditions: {name} is above {MAX_CONDITIONS_BYTES} bytes; a conditions table "
                         "lists conditions, not trials")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise ValueError(f"procedure.conditions: {name} is not UTF-8 text; save it as CSV (UTF-8)") from None
    table = list(csv.reader(io.StringIO(text)))
    if not table or not any(cell.strip() for cell in table[0]):
        raise ValueError(f"procedure.conditions: {name} is empty; give a header row and one row per condition")
    columns = []
    for header in table[0]:
        match = _HEADER.fullmatch(header)
        if not match or match.group(1) not in COLUMNS:
            raise ValueError(f"procedure.conditions: {name}: unknown column {header!r}; use {sorted(COLUMNS)}, each "
                             "with its unit in brackets, e.g. 'pitch [mm]'")
        field, dimension = COLUMNS[match.group(1)]
        unit = match.group(2)
        if dimension != "text" and unit is None:
            raise ValueError(f"procedure.conditions: {name}: column {header!r} has no unit; write it in brackets, "
                             f"e.g. '{match.group(1)} [{_EXAMPLE_UNIT[dimension]}]'")
        if dimension == "text" and unit is not None:
            raise ValueError(f"procedure.conditions: {name}: column {header!r}: surface takes no unit; write 'surface'")
        if field in [c[0] for c in columns]:
            raise ValueError(f"procedure.conditions: {name}: column {match.group(1)!r} appears twice; keep one")
        columns.append((field, dimension, unit))
    body = [(i, row) for i, row in enumerate(table[1:], start=2) if any(cell.strip() for cell in row)]
    if not body:
        raise ValueError(f"procedure.conditions: {name} has a header but no conditions; add one row per condition")
    if len(body) > MAX_CONDITIONS:
        raise ValueError(f"procedure.conditions: {name} has {len(body)} rows, above {MAX_CONDITIONS}; split the design")
    rows = []
    for i, cells in body:  # i: the line in the file (1 is the header)
        if len(cells) != len(columns):
            raise ValueError(f"procedure.conditions: {name} line {i}: {len(cells)} cells for {len(columns)} columns")
        row = {}
        for (field, dimension, unit), cell in zip(columns, cells):
            cell = cell.strip()
            if not cell:
                raise ValueError(f"procedure.conditions: {name} line {i}: empty cell in column {field}; fill it in")
            row[field] = cell if dimension == "text" else to_si(f"{cell}{unit}", dimension, name=f"{name} line {i} {field}")
        rows.append(row)
    return check_rows(rows, name)


def check_rows(rows: Any, where: str = "procedure.conditions") -> list[dict[str, Any]]:
    """Validate condition rows (dicts of stimulus fields; numbers in SI or strings with units) to SI.

    Raises
    ------
    ValueError
        Not a non-empty list of tables, an unknown field, a surface other than sinusoid or
        square, rows with different fields, or a repeated condition.
    """
    if not isinstance(rows, list) or not rows or not all(isinstance(r, dict) for r in rows):
        raise ValueError(f"{where}: must be a non-empty list of conditions (tables of stimulus fields), got {rows!r}")
    out, seen = [], {}
    for i, row in enumerate(rows):
        unknown = sorted(set(row) - set(FIELDS))
        if unknown:
            raise ValueError(f"{where}: condition {i} has unknown fields {unknown}; use {sorted(FIELDS)}")
        if set(row) != set(rows[0]):
            raise ValueError(f"{where}: condition {i} sets {sorted(row)}, condition 0 sets {sorted(rows[0])}; every "
                             "condition sets the same fields")
        clean = {}
        for field, value in row.items():
            if FIELDS[field] == "text":
                if value not in ("sinusoid", "square"):
                    raise ValueError(f"{where}: condition {i} surface must be 'sinusoid' or 'square', got {value!r}")
                clean[field] = value
            else:
                clean[field] = to_si(value, FIELDS[field], name=field)
        key = tuple(sorted(clean.items()))
        if key in seen:
            raise ValueError(f"{where}: conditions {seen[key]} and {i} are the same ({clean}); list each condition "
                             "once (repeats_per_block repeats it)")
        seen[key] = i
        out.append(clean)
    return out


def condition_levels(data: dict) -> dict:
    """A constant-stimuli ``[procedure]`` table with its ``conditions`` rows validated to SI and
    ``levels`` derived from them (each row's value of ``parameter``).

    Raises
    ------
    ValueError
        The conditions are a file name (read only by ``Protocol.from_toml``), a row is invalid
        (:func:`check_rows`), no column is the varied parameter, or ``levels`` is given too.
    """
    rows = data["conditions"]
    if isinstance(rows, str):
        raise ValueError(f"conditions: the file {rows!r} is read when the protocol is loaded from its file "
                         "(Protocol.from_toml, `tactilab experiment run`); from Python, pass the rows")
    rows = check_rows(rows, "conditions")
    parameter = data.get("parameter")
    if parameter not in rows[0]:
        raise ValueError(f"conditions: no column for the varied parameter {parameter!r} (columns: {sorted(rows[0])}); "
                         "add it, or vary a parameter the table lists")
    derived = [row[parameter] for row in rows]
    if data.get("levels") is not None and data["levels"] != derived:
        raise ValueError("levels: give levels or a conditions table, not both (the table's column of the varied "
                         "parameter gives the levels)")
    return {**data, "conditions": rows, "levels": derived}
