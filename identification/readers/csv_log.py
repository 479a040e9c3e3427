"""CSV flight logs with a column map: ``{canonical_name: column}``; a ``time`` column in seconds."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from identification.flightlog import (
    BATTERY_CURRENT,
    BATTERY_VOLTAGE,
    BATTERY_VOLTAGE_LEGACY,
    FlightLog,
    LogError,
    Signal,
    add_battery,
)


def read_csv(path: Path, column_map: dict[str, str] | None = None, time_column: str = "time_s") -> FlightLog:
    """Every numeric column becomes a signal; ``column_map`` renames columns to canonical names."""
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    if len(rows) < 2:
        raise LogError(f"{path}: a CSV log needs a header row and at least one data row")
    header = [h.strip() for h in rows[0]]
    if time_column not in header:
        raise LogError(f"{path}: no time column {time_column!r}; columns are {', '.join(header)}")
    data: dict[str, list[float]] = {h: [] for h in header}
    kept = 0
    for lineno, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            break  # a truncated last line: keep what came before
        try:
            vals = [float(v) for v in row]
        except ValueError as err:
            raise LogError(f"{path}: line {lineno}: {err}") from err
        for h, v in zip(header, vals, strict=True):
            data[h].append(v)
        kept += 1
    warnings = []
    if kept < len(rows) - 1:
        warnings.append(f"{path}: {len(rows) - 1 - kept} incomplete line(s) at the end were dropped")
    t = np.array(data.pop(time_column))
    rename = {v: k for k, v in (column_map or {}).items()}
    missing = [c for c in rename if c not in data]
    if missing:
        raise LogError(f"{path}: mapped column(s) {', '.join(missing)} not found; columns are {', '.join(header)}")
    signals = {}
    for col, vals in data.items():
        name = rename.get(col, col)
        signals[name] = Signal(name, t, np.array(vals), "", f"CSV column {col}")
    volt = signals.pop(BATTERY_VOLTAGE, None) or signals.pop(BATTERY_VOLTAGE_LEGACY, None)
    curr = signals.pop(BATTERY_CURRENT, None)
    if volt is not None or curr is not None:  # units V and A, unmeasured (0 V, NaN) samples left out
        add_battery(signals, t, None if volt is None else volt.values, None if curr is None else curr.values, "CSV")
    return FlightLog(str(path), "csv", signals, {}, None, warnings)
