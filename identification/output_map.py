"""Which FMU output is compared with which logged signal, with unit, frame and angle handling (TOML config).

```toml
[thresholds]
max_theil = 0.3                  # pass when Theil's U is below this (default for every signal)

[signals.yaw_rad]                # FMU output
log = "yaw_rad"                  # canonical log signal or raw "MSG.Field"
log_unit = "rad"                 # unit of the log values; converted to the FMU output's unit (deg, cm, kn, ...)
scale = 1.0                      # after unit conversion; -1 flips an axis (FLU -> FRD, up -> down)
scale_by_param = ""              # multiply by an FMU parameter too (e.g. mass_kg: specific force -> force)
offset = 0.0
wrap = true                      # angle: compare modulo 2 pi
max_theil = 0.5                  # per-signal threshold
max_rmse = 0.02                  # also passes when the RMSE is below this (signal units): Theil's U means
                                 # little for a signal that barely moves (attitude of a hovering quadrotor)
```
A ``[signals]`` table replaces the vehicle's default map; ``[signals_extra]`` adds to it.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

DEFAULT_MAX_THEIL = 0.3
G0_M_S2 = 9.80665

#: log unit -> (SI unit, factor)
UNIT_CONVERSIONS: dict[str, tuple[str, float]] = {
    "deg": ("rad", math.pi / 180), "cdeg": ("rad", math.pi / 18000), "deg/s": ("rad/s", math.pi / 180),
    "cm": ("m", 0.01), "mm": ("m", 0.001), "ft": ("m", 0.3048), "km": ("m", 1000.0),
    "cm/s": ("m/s", 0.01), "kn": ("m/s", 1852 / 3600), "km/h": ("m/s", 1 / 3.6), "ft/s": ("m/s", 0.3048),
    "g": ("m/s2", G0_M_S2), "mG": ("m/s2", G0_M_S2 / 1000), "kN": ("N", 1000.0),
}


class OutputMapError(ValueError):
    """A bad output-map config or a unit that does not fit the FMU output; names file, signal and value."""


@dataclass(frozen=True)
class SignalMap:
    fmu: str
    log: str
    log_unit: str | None = None
    scale: float = 1.0
    scale_by_param: str | None = None
    offset: float = 0.0
    wrap: bool = False
    max_theil: float = DEFAULT_MAX_THEIL
    max_rmse: float | None = None

    def passes(self, theil_u: float, rmse: float) -> bool:
        """Theil's U below ``max_theil``, or the RMSE within the absolute tolerance ``max_rmse``."""
        return bool(theil_u < self.max_theil or (self.max_rmse is not None and rmse < self.max_rmse))

    def convert(self, values: np.ndarray, fmu_unit: str | None, params: Mapping[str, float]) -> np.ndarray:
        """Log values in the FMU output's unit and frame."""
        factor = self.scale
        if self.log_unit:
            si, f = UNIT_CONVERSIONS.get(self.log_unit, (self.log_unit, 1.0))
            if fmu_unit and si != fmu_unit:
                raise OutputMapError(f"signals.{self.fmu}: log unit {self.log_unit!r} converts to {si!r}, but the "
                                     f"FMU output is in {fmu_unit!r}")
            factor *= f
        if self.scale_by_param:
            if self.scale_by_param not in params:
                raise OutputMapError(f"signals.{self.fmu}.scale_by_param: {self.scale_by_param!r} is not an FMU "
                                     "parameter")
            factor *= params[self.scale_by_param]
        return np.asarray(values, dtype=float) * factor + self.offset

    def align(self, model: np.ndarray, measured: np.ndarray) -> np.ndarray:
        """Model values brought within pi of the measurement for angles (``wrap``), else unchanged."""
        if not self.wrap:
            return model
        return measured + (model - measured + math.pi) % (2 * math.pi) - math.pi


#: absolute tolerances of the default maps: ~1 deg of attitude, ~2 deg/s of body rate (a few sensor sigmas)
ANGLE_TOL_RAD, RATE_TOL_RAD_S = 0.02, 0.035


def _gyro(axis: str) -> SignalMap:
    return SignalMap(f"rate_body_{axis}_rad_s", f"gyro_body_{axis}_rad_s", max_rmse=RATE_TOL_RAD_S)


def _angle(name: str, wrap: bool = False) -> SignalMap:
    return SignalMap(name, name, wrap=wrap, max_rmse=ANGLE_TOL_RAD)


QUADROTOR = (
    SignalMap("altitude_m", "altitude_m"), _angle("roll_rad"), _angle("pitch_rad"), _angle("yaw_rad", wrap=True),
    _gyro("x"), _gyro("y"), _gyro("z"),
    # paper 000 Fig. 5: the thrust map's force against the measured F_z = -m a_z (specific force, FRD)
    SignalMap("thrust_total_N", "accel_body_z_m_s2", scale=-1.0, scale_by_param="mass_kg"),
)
FIXED_WING = (
    _angle("roll_rad"), _angle("pitch_rad"), _angle("yaw_rad", wrap=True), _gyro("x"), _gyro("y"), _gyro("z"),
    SignalMap("airspeed_m_s", "airspeed_m_s"),
    SignalMap("accel_body_x_m_s2", "accel_body_x_m_s2"), SignalMap("accel_body_y_m_s2", "accel_body_y_m_s2"),
    SignalMap("accel_body_z_m_s2", "accel_body_z_m_s2"), SignalMap("altitude_m", "altitude_m"),
)
DEFAULTS = {"quadrotor": QUADROTOR, "fixed_wing": FIXED_WING}
FIELDS = {"log": str, "log_unit": str, "scale": (int, float), "scale_by_param": str, "offset": (int, float),
          "wrap": bool, "max_theil": (int, float), "max_rmse": (int, float)}


def load(path: str | Path | None, vehicle: str) -> tuple[SignalMap, ...]:
    """The vehicle's default map, or the map of a TOML file (every problem reported at once)."""
    if vehicle not in DEFAULTS:
        raise OutputMapError(f"no default output map for vehicle {vehicle!r} (known: {', '.join(DEFAULTS)})")
    if path is None:
        return DEFAULTS[vehicle]
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text())
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise OutputMapError(f"{p}: cannot read the output map ({err})") from err
    return from_dict(data, vehicle, str(p))


def from_dict(data: Mapping[str, Any], vehicle: str, source: str = "output map") -> tuple[SignalMap, ...]:
    problems: list[str] = []
    limit = data.get("thresholds", {}).get("max_theil", DEFAULT_MAX_THEIL)
    if not (isinstance(limit, int | float) and limit > 0):
        problems.append(f"thresholds.max_theil = {limit!r}; allowed: a number > 0")
        limit = DEFAULT_MAX_THEIL
    base = {} if "signals" in data else {m.fmu: replace(m, max_theil=limit) for m in DEFAULTS[vehicle]}
    for table in ("signals", "signals_extra"):
        for fmu, raw in (data.get(table) or {}).items():
            if not isinstance(raw, Mapping):
                problems.append(f"{table}.{fmu} must be a table")
                continue
            unknown = [k for k in raw if k not in FIELDS]
            if unknown:
                problems.append(f"{table}.{fmu}: unknown field(s) {', '.join(unknown)} (known: {', '.join(FIELDS)})")
            bad = [f"{k} = {v!r}" for k, v in raw.items() if k in FIELDS and not isinstance(v, FIELDS[k])]
            if bad:
                problems.append(f"{table}.{fmu}: wrong type: {', '.join(bad)}")
            if "log" not in raw:
                problems.append(f"{table}.{fmu}: 'log' (the logged signal) is required")
            if unknown or bad or "log" not in raw:
                continue
            if raw.get("log_unit") and raw["log_unit"] not in UNIT_CONVERSIONS and "/" not in raw["log_unit"] \
                    and raw["log_unit"] not in ("m", "rad", "m/s", "m/s2", "rad/s", "N", "1", "s"):
                problems.append(f"{table}.{fmu}.log_unit = {raw['log_unit']!r}; known: "
                                f"{', '.join(UNIT_CONVERSIONS)} or an SI unit")
            for key in ("max_theil", "max_rmse"):
                if key in raw and not raw[key] > 0:
                    problems.append(f"{table}.{fmu}.{key} = {raw[key]!r}; allowed: > 0")
            base[fmu] = SignalMap(fmu=fmu, **{"max_theil": limit, **raw})
    if problems:
        raise OutputMapError(f"{source}: " + "; ".join(problems))
    if not base:
        raise OutputMapError(f"{source}: no signals to compare")
    return tuple(base.values())
