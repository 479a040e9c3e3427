"""The ``battery_voltage_V`` input of a quadrotor replay from the identified battery-state model.

``uavfmu identify thrust`` writes the battery-state model beside the thrust map (``_identification.battery_state``
of the parameter file): the logged voltage, or a hover-condition state with time constant ``tau_s``
(:mod:`identification.thrust.battery`), or none. A replay given that file (``uavfmu validate --params FILE``)
drives the FMU's ``battery_voltage_V`` input from the log itself:

1. ``logged``: the log's battery voltage, when it has one;
2. ``hover battery state``: else the equivalent voltage ``V_nom s(t)`` of the hover-condition state, computed
   from the log's motor PWM, climb rate and attitude by the identification code
   (:func:`identification.thrust.model.battery_input_V`): the same function the identification scored;
3. ``nominal``: else (a file without a state) ``battery_nominal_V``, as without the file.

The source used is printed and written to ``metrics.json``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fmu_models.common.atmosphere import G0_M_S2
from fmu_models.common.errors import ParameterError
from fmu_models.common.params import read_json
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.params import QuadrotorParams
from identification.thrust.battery import HOVER_CLIMB_M_S
from identification.thrust.dataset import MOTOR_MIN_PWM_US, without_ground_contact
from identification.thrust.model import FlightData, ModelSpec, battery_input_V

INPUT = "battery_voltage_V"
LOGGED = "battery_voltage_v"  #: the log's canonical battery voltage signal
#: mean motor PWM above which a sample is airborne [us] (``identify thrust``'s default ``--motor-min-pwm-us``)
AIRBORNE_MEAN_PWM_US = MOTOR_MIN_PWM_US
#: FMU parameters that must equal the file's for the state to mean the same thing in the FMU
MATCH = ("battery_nominal_V", "thrust_voltage_exponent", "pwm_idle_us", "pwm_full_us")


@dataclass(frozen=True)
class BatteryStateModel:
    """The thrust function and battery-state structure a replay needs to compute ``battery_voltage_V``."""

    params: QuadrotorParams
    spec: ModelSpec
    hover_climb_m_s: float
    source: str

    @property
    def has_state(self) -> bool:
        return self.spec.tau_s is not None


def read_battery_state(path: str | Path) -> BatteryStateModel | None:
    """The battery-state model of a parameter file written by ``identify thrust``; None when the file has none.
    :class:`ParameterError` naming the file and field when it is malformed."""
    return battery_state_of(read_json(path), str(path))


def embedded_battery_state(fmu: str | Path) -> BatteryStateModel | None:
    """The battery-state model of the parameter file an FMU was built from (``build --params`` embeds it as
    ``fmu_models.fmi.fmuzip.EMBEDDED_PARAMS``); None when the FMU carries none or the file has no state.
    :class:`ParameterError` naming the FMU and the member when it is malformed."""
    from fmu_models.fmi.fmuzip import embedded_params

    found = embedded_params(Path(fmu))
    return None if found is None else battery_state_of(*found)


def job_battery_state(fmu: str | Path, params_file: str | Path | None, embedded: bool, vehicle: str
                      ) -> BatteryStateModel | None:
    """The battery-state model a replay of ``fmu`` (a ``vehicle`` FMU) uses: ``params_file``'s, else (``embedded``)
    the one of the file the FMU was built from, else None. The embedded file is a default: ``build --params``
    embeds it in every FMU it builds, and its battery state is the quadrotor's, so a fixed-wing FMU ignores it
    (a ``params_file`` named for one is refused by :func:`feed`). The nominal run and every Monte Carlo draw
    call this one function."""
    if params_file is not None:
        return read_battery_state(params_file)
    return embedded_battery_state(fmu) if embedded and vehicle == "quadrotor" else None


def battery_state_of(data: dict[str, Any], path: str) -> BatteryStateModel | None:
    """The battery-state model of parameter-file contents ``data`` read from ``path`` (named in errors)."""
    ident = data.get("_identification") if isinstance(data, dict) else None
    info = ident.get("battery_state") if isinstance(ident, dict) else None
    if not isinstance(info, dict) or not isinstance(data.get("quadrotor"), dict):
        return None
    p = QuadrotorParams.from_dict(data["quadrotor"], source=f"{path}: quadrotor")
    method = str(info.get("method", ""))
    tau = info.get("tau_s") if method.startswith("hover condition") else None
    climb = info.get("hover_climb_m_s", HOVER_CLIMB_M_S)
    for name, v, lo, hi in (("tau_s", tau, 1e-3, 1e6), ("hover_climb_m_s", climb, 1e-3, 10.0)):
        if v is not None and not (isinstance(v, int | float) and math.isfinite(v) and lo <= v <= hi):
            raise ParameterError(str(path), [f"_identification.battery_state.{name} = {v!r}: allowed {lo:g}..{hi:g}"])
    spec = ModelSpec(p.pwm_idle_us, p.pwm_full_us, p.battery_nominal_V, method.startswith("logged"),
                     tau_s=None if tau is None else float(tau))
    return BatteryStateModel(p, spec, float(climb), str(path))


def mismatches(model: BatteryStateModel, fmu_params: dict[str, float]) -> list[str]:
    """FMU parameters that differ from the file's (the state would mean something else in that FMU)."""
    out = []
    for name in MATCH:
        mine, theirs = float(getattr(model.params, name)), fmu_params.get(name)
        if theirs is not None and not math.isclose(mine, float(theirs), rel_tol=1e-6, abs_tol=1e-9):
            out.append(f"{name} = {theirs:g} in the FMU, {mine:g} in {model.source}")
    return out


def battery_input(model: BatteryStateModel, log: Any, t_s: np.ndarray, inputs: dict[str, np.ndarray],
                  mass_kg: float) -> tuple[np.ndarray, dict[str, Any]]:
    """``battery_voltage_V`` [V] on the replay grid ``t_s`` and where it came from (``{"source", "detail"}``)."""
    if log.has(LOGGED):
        return log.signal(LOGGED).resample(t_s), {"source": "logged", "detail": f"the log's {LOGGED}"}
    nominal = model.params.battery_nominal_V
    if not model.has_state:
        return np.full(len(t_s), nominal), {"source": "nominal", "detail": f"{model.source} has no hover battery "
                                            f"state and the log no voltage: battery_nominal_V = {nominal:g} V"}
    pwm = np.stack([inputs[f"pwm_{k}_us"] for k in range(1, N_MOTORS + 1)], axis=1)
    airborne = without_ground_contact(pwm.mean(axis=1) > AIRBORNE_MEAN_PWM_US, t_s)
    climb = _climb(log, t_s)
    hover = airborne if climb is None else airborne & (np.abs(climb) < model.hover_climb_m_s)
    tilt = None
    if log.has("roll_rad") and log.has("pitch_rad"):
        tilt = np.cos(log.signal("roll_rad").resample(t_s)) * np.cos(log.signal("pitch_rad").resample(t_s))
    period = float(np.median(np.diff(t_s))) if len(t_s) > 1 else 1.0
    f = FlightData("replay", pwm, None, hover, np.asarray(t_s, float), np.zeros(len(t_s)), mass_kg * G0_M_S2,
                   period, tilt)
    volt = battery_input_V(model.params, model.spec, f)
    return volt, {"source": "hover battery state",
                  "detail": f"hover-condition state (tau {model.spec.tau_s:g} s, {int(hover.sum())} hover samples) "
                            f"from the log's PWM{', climb rate' if climb is not None else ''}"
                            f"{', attitude' if tilt is not None else ''} and mass {mass_kg:g} kg",
                  "range_V": [float(volt.min()), float(volt.max())]}


def _climb(log: Any, t_s: np.ndarray) -> np.ndarray | None:
    if log.has("climb_rate_m_s"):
        return log.signal("climb_rate_m_s").resample(t_s)
    if log.has("vel_down_m_s"):
        return -log.signal("vel_down_m_s").resample(t_s)
    return None


def feed(model: BatteryStateModel, vehicle: str, fmu_params: dict[str, float], log: Any, t_s: np.ndarray,
         inputs: dict[str, np.ndarray], notes: list[str]) -> dict[str, Any]:
    """Replace the FMU's ``battery_voltage_V`` input in ``inputs`` by :func:`battery_input` (and drop the note
    that it was held); the source. ``ValueError`` naming what does not fit (vehicle, input, parameters)."""
    if vehicle != "quadrotor" or INPUT not in inputs:
        raise ValueError(f"{model.source} carries a quadrotor battery-state model; this FMU ({vehicle}) has no "
                         f"{INPUT} input")
    bad = mismatches(model, fmu_params)
    if bad:
        raise ValueError(f"the FMU was not built from {model.source}: " + "; ".join(bad))
    volt, source = battery_input(model, log, t_s, inputs, float(fmu_params.get("mass_kg", model.params.mass_kg)))
    inputs[INPUT] = volt
    notes[:] = [n for n in notes if not n.startswith(f"FMU input {INPUT} ")]
    return {**source, "params": model.source}
