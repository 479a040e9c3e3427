"""Frozen parameter dataclasses: metadata per field, JSON loading with every problem reported at once."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any, TypeVar

from fmu_models.common.errors import ProblemList
from fmu_models.common.model import Variable

T = TypeVar("T")


def param(default: float, unit: str, lo: float | None, hi: float | None, description: str) -> Any:
    """A dataclass field of a physical parameter, with its unit, allowed range and meaning."""
    return dataclasses.field(
        default=default, metadata={"unit": unit, "min": lo, "max": hi, "description": description}
    )


def numeric_fields(cls: type) -> list[dataclasses.Field]:
    """The fields of a parameter dataclass that carry unit metadata (the scalar physical parameters)."""
    return [f for f in dataclasses.fields(cls) if "unit" in f.metadata]


def to_variables(params: Any) -> tuple[Variable, ...]:
    """FMU/model variables of the scalar parameters, with the instance's values as start values."""
    return tuple(
        Variable(
            f.name,
            f.metadata["unit"],
            f.metadata["description"],
            float(getattr(params, f.name)),
            f.metadata["min"],
            f.metadata["max"],
        )
        for f in numeric_fields(type(params))
    )


def check_scalars(cls: type, values: dict[str, Any], probs: ProblemList) -> dict[str, float]:
    """Range-check the scalar parameters given in ``values``; return them as floats."""
    out: dict[str, float] = {}
    for f in numeric_fields(cls):
        if f.name in values:
            probs.check_range(f.name, values[f.name], f.metadata["min"], f.metadata["max"])
            try:
                out[f.name] = float(values[f.name])
            except (TypeError, ValueError):
                pass
    return out


def unknown_keys(cls: type, values: dict[str, Any], probs: ProblemList, extra: tuple[str, ...] = ()) -> None:
    """Report keys that are not parameters of ``cls`` (typos would otherwise be silently ignored)."""
    known = {f.name for f in dataclasses.fields(cls)} | set(extra)
    for key in values:
        if not key.startswith("_") and key not in known:
            probs.add(f"{key} is not a parameter (known: {', '.join(sorted(known))})")


def read_json(path: str | Path) -> dict[str, Any]:
    """Read a JSON object from ``path`` with an error naming the file on failure."""
    p = Path(path)
    try:
        data = json.loads(p.read_text())
    except FileNotFoundError as err:
        raise FileNotFoundError(f"{p}: parameter file not found") from err
    except json.JSONDecodeError as err:
        raise ValueError(f"{p}: not valid JSON ({err.msg} at line {err.lineno}, column {err.colno})") from err
    if not isinstance(data, dict):
        raise ValueError(f"{p}: expected a JSON object at the top level, found {type(data).__name__}")
    return data
