"""PWM <-> FMU input mapping, one module for the HIL adapter, identification and validation.

Per channel: the source output index, min/trim/max PWM, reversal, deadband, the target FMU input and its
range, and a failsafe value. A pulse at trim maps to the middle of a symmetric range (surfaces) or to the
bottom of a one-sided one (throttle from min). Mapping files (TOML) are typed schemas
(:class:`MappingConfig`, ``fmu_models.config``): every problem is listed with file, field, value and range.

Sign conventions. The FMU's surface inputs follow Beard & McLain (uavbook): positive ``aileron_rad`` rolls
right (C_ell_delta_a > 0), positive ``elevator_rad`` is trailing edge down, nose down (C_m_delta_e < 0),
positive ``rudder_rad`` is trailing edge left, nose left (C_n_delta_r < 0). Autopilots command the other
way for pitch and yaw: a pulse above trim means roll right, nose up, nose right. ArduPilot: its SITL plane
(``libraries/SITL/SIM_Plane.cpp``) takes ``(pwm - 1500) / 500`` of outputs 1, 2, 4 with ``c_l_deltaa > 0``,
``c_m_deltae > 0``, ``c_n_deltar > 0``; ``SERVOn_REVERSED`` flips a channel on top. PX4: control group 0
carries roll, pitch, yaw torque demands about the FRD body axes (positive: roll right, nose up, nose
right), passed straight to the surfaces by the plane mixers (docs.px4.io v1.13, Mixing and Actuators).
So the default fixed-wing mappings reverse elevator and rudder (:data:`AUTOPILOT_REVERSED`): pull (PWM
above trim) gives nose up, right rudder gives nose right, and identified derivatives keep uavbook signs.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import Field

from fmu_models.config import ConfigError, FiniteFloat, Schema, validate_config
from fmu_models.quadrotor.constants import MOTOR_PWM_INPUTS

PWM_LIMITS_US = (500.0, 2500.0)  #: plausible servo pulse widths


#: FMU surface inputs whose uavbook sign is opposite to an autopilot's "PWM above trim" (nose up, nose right)
AUTOPILOT_REVERSED = {"aileron_rad": False, "elevator_rad": True, "rudder_rad": True, "throttle": False}


class MappingError(ValueError):
    """An invalid mapping config or PWM value; the message names the file, channel, field and value."""


class MappingConfigError(ConfigError, MappingError):
    """A mapping file or dict that does not validate; ``problems`` holds one line per problem."""


@dataclass(frozen=True)
class Channel:
    """One output channel mapped onto one FMU input."""

    target: str
    source: int
    min_us: float = 1000.0
    trim_us: float = 1500.0
    max_us: float = 2000.0
    out_min: float = -1.0
    out_max: float = 1.0
    reversed: bool = False
    deadband_us: float = 0.0
    failsafe: float = 0.0

    @property
    def one_sided(self) -> bool:
        """Throttle or motor: the range runs from ``min_us`` (at ``out_min``) to ``max_us``, no centre."""
        return self.out_min >= 0.0 or self.trim_us <= self.min_us

    def to_input(self, pwm_us: float) -> float:
        """FMU input value of a pulse width [us]; NaN or implausible pulses raise ``MappingError``."""
        if not (PWM_LIMITS_US[0] <= pwm_us <= PWM_LIMITS_US[1]):  # also catches NaN
            raise MappingError(f"channel {self.source} ({self.target}): PWM {pwm_us} us outside "
                               f"[{PWM_LIMITS_US[0]}, {PWM_LIMITS_US[1]}] us")
        lo, trim, hi = self.min_us, self.trim_us, self.max_us
        x = lo if pwm_us < lo else hi if pwm_us > hi else pwm_us
        if self.deadband_us and abs(x - trim) <= self.deadband_us:
            x = trim
        if self.out_min >= 0.0 or trim <= lo:  # one-sided target (throttle, motor)
            full = (x - lo) / (hi - lo)
            if self.reversed:
                full = 1.0 - full
            return self.out_min + full * (self.out_max - self.out_min)
        if x >= trim:
            frac = 0.0 if hi == trim else (x - trim) / (hi - trim)
        else:
            frac = -(trim - x) / (trim - lo)
        if self.reversed:
            frac = -frac
        return frac * (self.out_max if frac >= 0 else -self.out_min)

    def to_pwm(self, value: float) -> float:
        """The pulse width [us] that :meth:`to_input` maps to ``value`` (clipped to the channel's range);
        used to write synthetic logs as an autopilot would have logged its outputs."""
        v = min(max(value, self.out_min), self.out_max)
        if self.one_sided:
            full = (v - self.out_min) / (self.out_max - self.out_min)
            if self.reversed:
                full = 1.0 - full
            return self.min_us + full * (self.max_us - self.min_us)
        frac = v / self.out_max if v >= 0 else v / -self.out_min
        if self.reversed:
            frac = -frac
        return self.trim_us + frac * ((self.max_us - self.trim_us) if frac >= 0 else (self.trim_us - self.min_us))


class ChannelConfig(Schema):
    """One channel of a mapping file (``[channels.<fmu input>]``); ranges checked field by field."""

    source: int = Field(ge=1, le=32)  # autopilot output channel (SERVOn / actuator output n)
    min_us: float = Field(1000.0, ge=PWM_LIMITS_US[0], le=PWM_LIMITS_US[1])  # PWM giving out_min [us]
    trim_us: float = Field(1500.0, ge=PWM_LIMITS_US[0], le=PWM_LIMITS_US[1])  # PWM giving 0 [us], min..max
    max_us: float = Field(2000.0, ge=PWM_LIMITS_US[0], le=PWM_LIMITS_US[1])  # PWM giving out_max [us]
    out_min: FiniteFloat = -1.0  # FMU input at min_us [FMU unit: rad for surfaces, 0..1 throttle]
    out_max: FiniteFloat = 1.0  # FMU input at max_us [FMU unit], above out_min
    reversed: bool = False  # the servo turns the other way (SERVOn_REVERSED)
    deadband_us: float = Field(0.0, ge=0.0, le=500.0)  # |PWM - trim| below this gives 0 [us]
    failsafe: FiniteFloat = 0.0  # FMU input when the channel is missing or out of range [FMU unit]


class MappingConfig(Schema):
    """A mapping file: one table per FMU input under ``[channels]``."""

    channels: dict[str, ChannelConfig]


def _order_problems(target: str, raw: Mapping[str, Any]) -> list[str]:
    """Cross-field checks (min <= trim <= max, out_min < out_max) on whatever fields are numbers."""
    def num(key: str, default: float) -> float | None:
        v = raw.get(key, default)
        return float(v) if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) else None

    out = []
    lo, trim, hi = num("min_us", 1000.0), num("trim_us", 1500.0), num("max_us", 2000.0)
    if None not in (lo, trim, hi) and not (lo <= trim <= hi and lo < hi):  # type: ignore[operator]
        out.append(f"field channels.{target}: need min_us <= trim_us <= max_us and min_us < max_us "
                   f"(got {lo}, {trim}, {hi})")
    a, b = num("out_min", -1.0), num("out_max", 1.0)
    if a is not None and b is not None and not a < b:
        out.append(f"field channels.{target}: out_min {a} must be below out_max {b}")
    return out


@dataclass(frozen=True)
class PwmMapping:
    """All channels of a vehicle; ``apply(pwm_by_channel)`` gives the FMU inputs."""

    channels: tuple[Channel, ...]

    def apply(self, pwm_us: Mapping[int, float], failsafe: bool = False) -> dict[str, float]:
        if failsafe:
            return {c.target: c.failsafe for c in self.channels}
        out = {}
        for c in self.channels:
            if c.source not in pwm_us:
                raise MappingError(f"channel {c.source} ({c.target}) is not in the received outputs")
            out[c.target] = c.to_input(float(pwm_us[c.source]))
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "mapping") -> PwmMapping:
        """Validate a decoded mapping (``{"channels": {target: {...}}}`` or the bare channel tables);
        :class:`MappingConfigError` lists every problem with file, field, value and allowed range."""
        if not isinstance(data, Mapping):
            raise MappingConfigError(source, [f"(top level) = {data!r}: must be a table"])
        # a file with a [channels] table is validated whole (so unknown top-level keys are named)
        doc = dict(data) if "channels" in data else {"channels": dict(data)}
        tables = doc["channels"]
        if not isinstance(tables, Mapping):
            raise MappingConfigError(source, [f"field channels = {tables!r}: must be a table"])
        problems: list[str] = []
        try:
            cfg = validate_config(doc, MappingConfig, source)
        except ConfigError as err:
            problems += err.problems
            cfg = None
        for target, raw in tables.items():
            if isinstance(raw, Mapping):
                problems += _order_problems(str(target), raw)
        if problems or cfg is None:
            raise MappingConfigError(source, problems)
        return cls(tuple(Channel(target=t, **c.model_dump()) for t, c in cfg.channels.items()))

    @classmethod
    def load(cls, path: str | Path) -> PwmMapping:
        """Read a TOML mapping file; :class:`MappingConfigError` names the file and every bad field."""
        p = Path(path)
        try:
            data = tomllib.loads(p.read_text())
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as err:
            raise MappingConfigError(str(p), [f"cannot read mapping ({err})"]) from None
        return cls.from_dict(data, source=str(p))

    @classmethod
    def from_ardupilot(cls, params: Mapping[str, float], surface_limit_rad: float = 0.35) -> PwmMapping:
        """Fixed-wing surfaces and throttle from ArduPilot SERVOn_FUNCTION/MIN/TRIM/MAX/REVERSED.

        A pulse above trim on a non-reversed output means roll right, nose up, nose right (ArduPilot's
        convention, see the module docstring); elevator and rudder are reversed into the uavbook signs.
        """
        targets = {4: ("aileron_rad", -surface_limit_rad, surface_limit_rad),
                   19: ("elevator_rad", -surface_limit_rad, surface_limit_rad),
                   21: ("rudder_rad", -surface_limit_rad, surface_limit_rad), 70: ("throttle", 0.0, 1.0)}
        channels = []
        for n in range(1, 33):
            fn = params.get(f"SERVO{n}_FUNCTION")
            if fn is None or int(fn) not in targets:
                continue
            name, lo, hi = targets[int(fn)]
            mn, mx = params.get(f"SERVO{n}_MIN", 1100.0), params.get(f"SERVO{n}_MAX", 1900.0)
            trim = params.get(f"SERVO{n}_TRIM", (mn + mx) / 2) if name != "throttle" else mn
            rev = bool(params.get(f"SERVO{n}_REVERSED", 0)) != AUTOPILOT_REVERSED[name]
            channels.append(Channel(name, n, mn, trim, mx, lo, hi, rev))
        if not channels:
            raise MappingError("no SERVOn_FUNCTION for aileron (4), elevator (19), rudder (21) or throttle (70)")
        return cls(tuple(channels))


def default_mapping(vehicle: str) -> PwmMapping:
    """Quadrotor: outputs 1-4 are the motors' PWM as they are; fixed wing: ArduPlane's SERVO1-4 defaults
    (aileron, elevator, throttle, rudder; surfaces +/-0.35 rad over 1100..1900 us, above trim = roll right,
    nose up, nose right as ArduPlane and PX4 command them; elevator and rudder reversed into uavbook signs)."""
    if vehicle == "quadrotor":
        return PwmMapping(tuple(Channel(name, k, 1000.0, 1000.0, 2000.0, 1000.0, 2000.0, failsafe=1000.0)
                                for k, name in enumerate(MOTOR_PWM_INPUTS, start=1)))
    surf = {"min_us": 1100.0, "trim_us": 1500.0, "max_us": 1900.0, "out_min": -0.35, "out_max": 0.35}
    return PwmMapping.from_dict({"channels": {
        "aileron_rad": {"source": 1, **surf}, "elevator_rad": {"source": 2, **surf, "reversed": True},
        "throttle": {"source": 3, "min_us": 1000.0, "trim_us": 1000.0, "max_us": 2000.0, "out_min": 0.0,
                     "out_max": 1.0},
        "rudder_rad": {"source": 4, **surf, "reversed": True}}}, source="default fixed-wing mapping")


def ardupilot_servo_reversed(channel: Channel) -> bool:
    """The ``SERVOn_REVERSED`` value an ArduPilot log carries for ``channel`` (inverse of
    :meth:`PwmMapping.from_ardupilot`'s convention reversal)."""
    return channel.reversed != AUTOPILOT_REVERSED.get(channel.target, False)
