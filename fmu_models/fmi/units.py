"""Unit strings of the project (``kg.m2``, ``N.s/m``, ``rad/s2``) -> FMI 2.0 ``BaseUnit`` exponents.

Hand-written because no maintained library emits FMI BaseUnit definitions; the grammar is small:
factors joined by ``.`` (multiply) and one ``/`` (divide), each an atom with an optional integer power.
"""

from __future__ import annotations

import re

from fmu_models.common.units import DEG_TO_RAD, RPM_TO_RAD_S

BASES = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")

#: atom -> (exponents over BASES, factor to SI)
ATOMS: dict[str, tuple[dict[str, int], float]] = {
    "kg": ({"kg": 1}, 1.0),
    "g": ({"kg": 1}, 1e-3),
    "m": ({"m": 1}, 1.0),
    "cm": ({"m": 1}, 1e-2),
    "mm": ({"m": 1}, 1e-3),
    "s": ({"s": 1}, 1.0),
    "ms": ({"s": 1}, 1e-3),
    "us": ({"s": 1}, 1e-6),
    "rad": ({"rad": 1}, 1.0),
    "deg": ({"rad": 1}, DEG_TO_RAD),
    "rpm": ({"rad": 1, "s": -1}, RPM_TO_RAD_S),
    "N": ({"kg": 1, "m": 1, "s": -2}, 1.0),
    "Pa": ({"kg": 1, "m": -1, "s": -2}, 1.0),
    "hPa": ({"kg": 1, "m": -1, "s": -2}, 100.0),
    "J": ({"kg": 1, "m": 2, "s": -2}, 1.0),
    "W": ({"kg": 1, "m": 2, "s": -3}, 1.0),
    "A": ({"A": 1}, 1.0),
    "V": ({"kg": 1, "m": 2, "s": -3, "A": -1}, 1.0),
    "ohm": ({"kg": 1, "m": 2, "s": -3, "A": -2}, 1.0),
    "K": ({"K": 1}, 1.0),
    "1": ({}, 1.0),
}

_ATOM = re.compile(r"^([A-Za-z]+|1)(-?\d+)?$")


class UnitError(ValueError):
    """A unit string the parser does not understand."""


def parse_unit(unit: str) -> tuple[dict[str, int], float]:
    """Exponents over the SI bases and the factor to SI of ``unit``."""
    if unit in ("", "1"):
        return {}, 1.0
    num, _, den = unit.partition("/")
    exps: dict[str, int] = {}
    factor = 1.0
    for sign, part in ((1, num), (-1, den)):
        if not part:
            continue
        for tok in part.split("."):
            m = _ATOM.match(tok)
            if not m or m.group(1) not in ATOMS:
                raise UnitError(f"unit {unit!r}: unknown factor {tok!r} (known: {', '.join(ATOMS)})")
            power = sign * int(m.group(2) or 1)
            base, f = ATOMS[m.group(1)]
            for k, e in base.items():
                exps[k] = exps.get(k, 0) + e * power
            factor *= f**power
    return {k: v for k, v in exps.items() if v}, factor
