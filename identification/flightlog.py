"""One in-memory flight-log type: named signals, time in seconds from log start, SI units, NED/FRD frames.

Canonical signal names are listed in docs/interfaces.md; every raw field is also kept as ``MSG.Field`` in
the log's own units.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: canonical battery signals [V], [A] (``battery_voltage_V`` is kept as an alias of the voltage for older callers)
BATTERY_VOLTAGE, BATTERY_CURRENT, BATTERY_VOLTAGE_LEGACY = "battery_voltage_v", "battery_current_a", "battery_voltage_V"


class LogError(ValueError):
    """A log that cannot be read (missing, empty, corrupt); the message names the file."""


class MissingSignalError(LogError, KeyError):
    """A signal the caller needs is not in the log; the message names the file and what is there."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


@dataclass(frozen=True)
class Signal:
    """One time series: ``t_s`` [s] ascending and ``values`` in ``unit``."""

    name: str
    t_s: np.ndarray
    values: np.ndarray
    unit: str
    description: str = ""

    def resample(self, t_s: np.ndarray) -> np.ndarray:
        """Linear interpolation at ``t_s`` (held constant outside the recorded span)."""
        return np.interp(t_s, self.t_s, self.values)


@dataclass
class FlightLog:
    """Signals by name, logged parameters, vehicle kind and reader warnings of one log file."""

    source: str
    fmt: str
    signals: dict[str, Signal]
    params: dict[str, float]
    vehicle: str | None = None
    warnings: list[str] = field(default_factory=list)

    def signal(self, name: str) -> Signal:
        if name not in self.signals:
            canonical = sorted(n for n in self.signals if "." not in n)
            raise MissingSignalError(
                f"{self.source}: signal {name!r} is not in this {self.fmt} log; canonical signals present: "
                f"{', '.join(canonical) or 'none'}"
            )
        return self.signals[name]

    def has(self, name: str) -> bool:
        return name in self.signals

    @property
    def duration_s(self) -> float:
        ends = [s.t_s[-1] for s in self.signals.values() if len(s.t_s)]
        return float(max(ends)) if ends else 0.0

    def window(self, t0_s: float, t1_s: float) -> FlightLog:
        """The part of the log between ``t0_s`` and ``t1_s`` (times kept as in the full log)."""
        out = {}
        for n, s in self.signals.items():
            keep = (s.t_s >= t0_s) & (s.t_s <= t1_s)
            out[n] = Signal(n, s.t_s[keep], s.values[keep], s.unit, s.description)
        return FlightLog(self.source, self.fmt, out, dict(self.params), self.vehicle, list(self.warnings))


def add_battery(signals: dict[str, Signal], t_s: np.ndarray, voltage_v: np.ndarray | None,
                current_a: np.ndarray | None, source: str) -> None:
    """Add ``battery_voltage_v`` [V] / ``battery_current_a`` [A] when the log really measured them.

    Samples that are not finite, and voltages <= 0 (no sensor: ArduPilot logs 0, MAVLink 65535 mV is mapped
    to NaN by the caller), are left out; a current is added only with a measured voltage or when it is not
    all zero. A name already present (an earlier, better source) is kept.
    """
    t = np.asarray(t_s, dtype=float)
    if voltage_v is not None and BATTERY_VOLTAGE not in signals:
        v = np.asarray(voltage_v, dtype=float)
        keep = np.isfinite(v) & (v > 0.0) & np.isfinite(t)
        if keep.any():
            sig = Signal(BATTERY_VOLTAGE, t[keep], v[keep], "V", f"battery voltage from {source}")
            signals[BATTERY_VOLTAGE] = sig
            signals.setdefault(BATTERY_VOLTAGE_LEGACY, Signal(BATTERY_VOLTAGE_LEGACY, sig.t_s, sig.values, "V",
                                                              f"alias of {BATTERY_VOLTAGE}"))
    if current_a is not None and BATTERY_CURRENT not in signals:
        c = np.asarray(current_a, dtype=float)
        keep = np.isfinite(c) & np.isfinite(t)
        measured = BATTERY_VOLTAGE in signals or bool(np.any(c[keep] != 0.0))
        if keep.any() and measured:
            signals[BATTERY_CURRENT] = Signal(BATTERY_CURRENT, t[keep], c[keep], "A", f"battery current from {source}")
