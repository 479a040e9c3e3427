"""CSV flight logs with a column map: ``{canonical_name: column}``; a ``time`` column in seconds.

Rows with the wrong number of fields are skipped and counted (a truncated last line is the usual case);
cells that are not numbers read as NaN (counted when they reach a canonical signal); columns with no number
at all (text columns) are left out.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from identification.logs.flightlog import (
    BATTERY_CURRENT,
    BATTERY_VOLTAGE,
    BATTERY_VOLTAGE_LEGACY,
    DataQuality,
    FlightLog,
    LogError,
    Signal,
    add_battery,
    sanitize_log,
)


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")


def _rows(path: Path, quality: DataQuality) -> tuple[list[str], np.ndarray, list[str]]:
    """Header, the float rows of the right width, and warnings about skipped lines."""
    raw = path.read_bytes()
    quality.bytes_total = len(raw)
    text = raw.decode("utf-8", errors="replace").replace("\0", "")
    try:
        rows = list(csv.reader(text.splitlines()))
    except csv.Error as err:
        raise LogError(f"{path}: not a readable CSV file ({err})") from err
    if len(rows) < 2:
        raise LogError(f"{path}: a CSV log needs a header row and at least one data row")
    header = [h.strip() for h in rows[0]]
    if not any(header):
        raise LogError(f"{path}: the first line of a CSV log must be a header of column names; it is empty")
    good = [[_number(v) for v in row] for row in rows[1:] if len(row) == len(header)]
    bad_lines = [i for i, row in enumerate(rows[1:], start=2) if len(row) != len(header)]
    quality.messages_total = len(rows) - 1
    warnings = []
    if bad_lines:
        quality.messages_skipped = len(bad_lines)
        quality.bytes_skipped = sum(len(",".join(rows[i - 1])) + 1 for i in bad_lines)
        if bad_lines == [len(rows)]:
            warnings.append(f"{path}: 1 incomplete line(s) at the end were dropped")
        else:
            shown = ", ".join(str(i) for i in bad_lines[:5])
            warnings.append(f"{path}: {len(bad_lines)} incomplete line(s) dropped (line {shown}"
                            f"{', ...' if len(bad_lines) > 5 else ''}); the other rows were kept")
    return header, np.array(good, dtype=float).reshape(-1, len(header)), warnings


def read_csv(path: Path, column_map: dict[str, str] | None = None, time_column: str = "time_s") -> FlightLog:
    """Every numeric column becomes a signal; ``column_map`` renames columns to canonical names."""
    quality = DataQuality(str(path))
    header, data, warnings = _rows(path, quality)
    if time_column not in header:
        raise LogError(f"{path}: no time column {time_column!r}; columns are {', '.join(header)}")
    if not data.shape[0]:
        raise LogError(f"{path}: no complete data row (every line has the wrong number of fields)")
    rename = {v: k for k, v in (column_map or {}).items()}
    missing = [c for c in rename if c not in header]
    if missing:
        raise LogError(f"{path}: mapped column(s) {', '.join(missing)} not found; columns are {', '.join(header)}")
    t = data[:, header.index(time_column)]
    signals = {}
    for j, col in enumerate(header):
        if col == time_column or (col not in rename and not np.isfinite(data[:, j]).any()):
            continue
        name = rename.get(col, col)
        signals[name] = Signal(name, t, data[:, j], "", f"CSV column {col}")
    volt = signals.pop(BATTERY_VOLTAGE, None) or signals.pop(BATTERY_VOLTAGE_LEGACY, None)
    curr = signals.pop(BATTERY_CURRENT, None)
    if volt is not None or curr is not None:  # units V and A, unmeasured (0 V, NaN) samples left out
        add_battery(signals, t, None if volt is None else volt.values, None if curr is None else curr.values, "CSV")
    return sanitize_log(FlightLog(str(path), "csv", signals, {}, None, warnings), quality)
