"""Autopilot parameter files computed from the vehicle model itself (the FMU's parameter start values, default
or identified): ``autopilot_params(fmu, "arduplane" | "arducopter" | "px4") -> AutopilotParams``.

ArduPlane: the rate loops (``AP_FW_Controller``: ``out = FF*s*r + P*s^2*e + I*s^2*int(e) + D``, out in degrees
of a 45-degree full throw, ``s = SCALING_SPEED / airspeed``) are designed on the rate responses per surface
deflection at trim: roll ``p' = -a1 p + a2 da`` (uavbook ``a_phi1``, ``a_phi2``: roll damping, aileron power,
inertia with Jxz), pitch ``q' = M_q q + M_a da + M_de de`` (pitch damping, stiffness, elevator power, Jy), yaw
likewise (N_r, N_dr); feed-forward makes the steady rate exact, P places the loop with a first-order servo
(``servo_tau_s``) at damping ``zeta``. Speeds from the slowest speed the model can trim (stall or elevator
limit), attitude limits and TECS / landing time constants from the trimmed climb, glide and phugoid.
ArduCopter: hover throttle, ``MOT_THST_EXPO`` fitted to the thrust map's curvature over the spin range, spin
and battery settings. PX4: hover thrust, ``THR_MDL_FAC``, mutually consistent speed limits and the settings
for flight without a ground station or RC. Every value carries the formula it came from as a comment.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

log = logging.getLogger(__name__)
AUTOPILOTS = ("arduplane", "arducopter", "px4")
VEHICLE_OF = {"arduplane": "fixed_wing", "arducopter": "quadrotor", "px4": "quadrotor"}
#: ArduPilot's rate controllers saturate their output at 45 (degrees of the nominal full throw)
FULL_THROW_DEG = 45.0
SERVO_TAU_S = 0.05  #: surface servo time constant assumed by the design [s] (hobby servo, 0.1 s per 60 deg)


@dataclass(frozen=True)
class AutopilotParams:
    """A parameter set: values in file order, each with the reason (a comment line in the file)."""

    autopilot: str
    vehicle: str
    source: str
    values: dict[str, float] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)
    #: values the model asked for outside what the autopilot accepts, clamped (also ``# WARNING`` lines in the file)
    warnings: tuple[str, ...] = ()
    #: ArduPlane: the circuit mission (QGC WPL 110) whose final approach follows the derived glide path
    mission: str = ""
    #: ArduPlane: that glide path [deg below the horizon]
    glide_deg: float = math.nan

    def text(self) -> str:
        """The file: ArduPilot ``.parm`` (``NAME value``) or PX4 ``param set-default NAME value`` lines."""
        px4 = self.autopilot == "px4"
        head = "#!/bin/sh\n" if px4 else ""
        head += (f"# {self.autopilot} parameters computed by `uavfmu autopilot-params` from {self.source}\n"
                 "# (hil_adapter/autopilot_params.py); regenerate, do not edit by hand.\n")
        lines = [head.rstrip("\n")] + [f"# WARNING: {w}" for w in self.warnings]
        for name, value in self.values.items():
            note = self.notes.get(name)
            if note:
                lines.append(f"# {name}: {note}")
            shown = _fmt(value)
            lines.append(f"param set-default {name} {shown}" if px4 else f"{name:<16} {shown}")
        return "\n".join(lines) + "\n"

    def write(self, path: str | Path) -> Path:
        out = Path(path)
        out.write_text(self.text())
        return out


def _fmt(value: float) -> str:
    if float(value).is_integer():
        return str(int(value))
    return f"{value:.4g}"


class _Params:
    """Collects values with their notes, in order."""

    def __init__(self) -> None:
        self.values: dict[str, float] = {}
        self.notes: dict[str, str] = {}
        self.warnings: list[str] = []
        #: ArduPlane: the landing glide path [deg] (for the mission)
        self.glide_deg = math.nan

    def __call__(self, name: str, value: float, note: str = "", digits: int | None = None) -> float:
        if not math.isfinite(value):
            raise ValueError(f"{name} = {value}: the model gave no finite value ({note})")
        self.values[name] = round(value, digits) if digits is not None else value
        if note:
            self.notes[name] = note
        return self.values[name]

    def clamp(self, name: str, wanted: float, lo: float, hi: float, limit_source: str) -> float:
        """``wanted`` limited to the autopilot's ``[lo, hi]``; a clamp is recorded as a warning naming the value the
        model asked for and ``limit_source`` (where the autopilot sets the limit)."""
        value = min(hi, max(lo, wanted))
        if value != wanted:
            self.warnings.append(f"{name}: the model gives {wanted:.4g}, outside {lo:g}..{hi:g} ({limit_source}): "
                                 f"clamped to {value:g}")
            log.warning("%s", self.warnings[-1])
        return value

    def advise(self, name: str, value: float, lo: float, hi: float, limit_source: str) -> None:
        """Record a warning when ``value`` lies outside ``[lo, hi]``, a range the autopilot only documents (its
        parameter metadata, flagged by ground stations, not enforced by the firmware): the value is kept."""
        if not lo <= value <= hi:
            self.warnings.append(f"{name} = {value:.4g} lies outside {lo:g}..{hi:g}, the range documented in "
                                 f"{limit_source} (advisory: the firmware does not constrain it); kept, the design "
                                 "needs it")
            log.warning("%s", self.warnings[-1])


# ------------------------------------------------------------------------------------------ the model
def fmu_parameters(fmu: str | Path) -> dict[str, float]:
    """Start values of the FMU's parameters by name (modelDescription.xml; the FMU is not instantiated)."""
    from fmpy import read_model_description

    md = read_model_description(str(fmu))
    out = {}
    for v in md.modelVariables:
        if v.causality == "parameter" and v.start is not None and v.type == "Real":
            out[v.name] = float(v.start)
    return out


def _simulator(vehicle: str, starts: Mapping[str, float]) -> tuple[Any, np.ndarray]:
    """The Python form of the FMU's model and its parameter vector with the FMU's start values."""
    from fmu_models.common.simulate import Simulator

    if vehicle == "fixed_wing":
        from fmu_models.fixed_wing.model import FixedWingModel

        sim = Simulator(FixedWingModel())
    else:
        from fmu_models.quadrotor.model import QuadrotorModel

        sim = Simulator(QuadrotorModel())
    known = {k: v for k, v in starts.items() if k in sim.model.params.index}
    missing = sorted(set(sim.model.params.index) - set(known))
    if missing:
        raise ValueError(f"the FMU has no start value for the {vehicle} parameters {', '.join(missing[:8])}: "
                         "not an FMU built by uavfmu for this vehicle")
    return sim, sim.params(**known)


def vehicle_of(starts: Mapping[str, float]) -> str:
    """``fixed_wing`` or ``quadrotor`` from the parameter names."""
    if "C_ell_p" in starts:
        return "fixed_wing"
    if "arm_length_m" in starts:
        return "quadrotor"
    raise ValueError("neither a fixed-wing (C_ell_p) nor a quadrotor (arm_length_m) FMU")


def autopilot_params(fmu: str | Path, autopilot: str, servo_tau_s: float = SERVO_TAU_S) -> AutopilotParams:
    """The parameter set of ``autopilot`` computed from the FMU's own parameters."""
    if autopilot not in AUTOPILOTS:
        raise ValueError(f"autopilot {autopilot!r}: allowed {', '.join(AUTOPILOTS)}")
    if not 0.0 < servo_tau_s <= 0.5:
        raise ValueError(f"servo_tau_s = {servo_tau_s}: allowed 0 < tau <= 0.5 s")
    starts = fmu_parameters(fmu)
    vehicle = vehicle_of(starts)
    if vehicle != VEHICLE_OF[autopilot]:
        raise ValueError(f"{Path(fmu).name} is a {vehicle} model; {autopilot} flies a {VEHICLE_OF[autopilot]}")
    sim, p = _simulator(vehicle, starts)
    out = _Params()
    mission = ""
    if autopilot == "arduplane":
        from hil_adapter.autopilot_plane import arduplane, circuit_mission

        arduplane(sim, p, out, servo_tau_s)
        mission = circuit_mission(out.glide_deg)
    else:
        from hil_adapter.autopilot_copter import arducopter, px4

        (arducopter if autopilot == "arducopter" else px4)(sim, p, out)
    return AutopilotParams(autopilot, vehicle, Path(fmu).name, out.values, out.notes, tuple(out.warnings), mission,
                           out.glide_deg)


__all__ = ["AUTOPILOTS", "AutopilotParams", "autopilot_params", "fmu_parameters", "vehicle_of"]
