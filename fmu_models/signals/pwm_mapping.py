"""PWM <-> FMU input mapping, one module for the HIL adapter, identification and validation.

Per channel: the source output index, min/trim/max PWM, reversal, deadband, the target FMU input and its
range, and a failsafe value. A pulse at trim maps to the middle of a symmetric range (surfaces) or to the
bottom of a one-sided one (throttle from min); configs are TOML or a dict, checked with every problem listed.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

PWM_LIMITS_US = (500.0, 2500.0)  #: plausible servo pulse widths


class MappingError(ValueError):
    """An invalid mapping config or PWM value; the message names the file, channel, field and value."""


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
        problems: list[str] = []
        channels = []
        for target, raw in (data.get("channels", data)).items():
            if not isinstance(raw, Mapping):
                problems.append(f"channels.{target} must be a table")
                continue
            try:
                ch = Channel(target=target, **{k: raw[k] for k in raw})
            except TypeError as err:
                problems.append(f"channels.{target}: {err}")
                continue
            for f in ("min_us", "trim_us", "max_us"):
                v = getattr(ch, f)
                if not (isinstance(v, int | float) and math.isfinite(v) and PWM_LIMITS_US[0] <= v <= PWM_LIMITS_US[1]):
                    problems.append(f"channels.{target}.{f} = {v!r}; allowed {PWM_LIMITS_US[0]}..{PWM_LIMITS_US[1]}")
            if not ch.min_us <= ch.trim_us <= ch.max_us or ch.min_us == ch.max_us:
                problems.append(f"channels.{target}: need min_us <= trim_us <= max_us and min_us < max_us "
                                f"(got {ch.min_us}, {ch.trim_us}, {ch.max_us})")
            if not ch.out_min < ch.out_max:
                problems.append(f"channels.{target}: out_min {ch.out_min} must be below out_max {ch.out_max}")
            if not (isinstance(ch.source, int) and 1 <= ch.source <= 32):
                problems.append(f"channels.{target}.source = {ch.source!r}; allowed 1..32")
            channels.append(ch)
        if problems:
            raise MappingError(f"{source}: " + "; ".join(problems))
        return cls(tuple(channels))

    @classmethod
    def load(cls, path: str | Path) -> PwmMapping:
        p = Path(path)
        try:
            data = tomllib.loads(p.read_text())
        except (OSError, tomllib.TOMLDecodeError) as err:
            raise MappingError(f"{p}: cannot read mapping ({err})") from err
        return cls.from_dict(data, source=str(p))

    @classmethod
    def from_ardupilot(cls, params: Mapping[str, float], surface_limit_rad: float = 0.35) -> PwmMapping:
        """Fixed-wing surfaces and throttle from ArduPilot SERVOn_FUNCTION/MIN/TRIM/MAX/REVERSED."""
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
            channels.append(Channel(name, n, mn, trim, mx, lo, hi, bool(params.get(f"SERVO{n}_REVERSED", 0))))
        if not channels:
            raise MappingError("no SERVOn_FUNCTION for aileron (4), elevator (19), rudder (21) or throttle (70)")
        return cls(tuple(channels))


def default_mapping(vehicle: str) -> PwmMapping:
    """Quadrotor: outputs 1-4 are the motors' PWM as they are; fixed wing: ArduPlane's SERVO1-4 defaults
    (aileron, elevator, throttle, rudder; surfaces +/-0.35 rad over 1100..1900 us)."""
    if vehicle == "quadrotor":
        return PwmMapping(tuple(Channel(f"pwm_{k}_us", k, 1000.0, 1000.0, 2000.0, 1000.0, 2000.0, failsafe=1000.0)
                                for k in range(1, 5)))
    surf = {"min_us": 1100.0, "trim_us": 1500.0, "max_us": 1900.0, "out_min": -0.35, "out_max": 0.35}
    return PwmMapping.from_dict({"channels": {
        "aileron_rad": {"source": 1, **surf}, "elevator_rad": {"source": 2, **surf},
        "throttle": {"source": 3, "min_us": 1000.0, "trim_us": 1000.0, "max_us": 2000.0, "out_min": 0.0,
                     "out_max": 1.0},
        "rudder_rad": {"source": 4, **surf}}}, source="default fixed-wing mapping")
