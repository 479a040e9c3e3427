"""What replay and identification take from a log: input samples and the vehicle's state at an instant."""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

from fmu_models.common.rigid_body import quat_from_euler, quat_to_dcm
from hil_adapter.pwm_mapping import MappingError, PwmMapping
from identification.flightlog import FlightLog, Signal


def resample_angle(sig: Signal, t_s: np.ndarray) -> np.ndarray:
    """An angle [rad] at ``t_s``, interpolated on the unwrapped series (logs wrap yaw at 0/360 deg: plain
    interpolation across the wrap gives 180 deg), wrapped back to (-pi, pi]."""
    unwrapped = np.interp(t_s, sig.t_s, np.unwrap(sig.values))
    return np.angle(np.exp(1j * unwrapped))


def hold(sig: Signal, t_s: np.ndarray) -> np.ndarray:
    """Zero-order hold of ``sig`` at ``t_s``: commanded outputs (servo PWM) hold between log samples."""
    idx = np.clip(np.searchsorted(sig.t_s, t_s, side="right") - 1, 0, len(sig.t_s) - 1)
    return sig.values[idx]


def mapped_inputs(names: Sequence[str], log: FlightLog, mapping: PwmMapping, t_s: np.ndarray) -> np.ndarray:
    """FMU/model inputs ``names`` (len(t) x len(names)) from the log's servo PWM through ``mapping``."""
    by_target = {c.target: c for c in mapping.channels}
    missing = [n for n in names if n not in by_target]
    if missing:
        raise MappingError(f"the PWM mapping has no channel for the inputs {', '.join(missing)}")
    u = np.empty((len(t_s), len(names)))
    for i, name in enumerate(names):
        ch = by_target[name]
        pwm = hold(log.signal(f"servo_{ch.source}_pwm_us"), t_s)
        try:
            u[:, i] = [ch.to_input(float(v)) for v in pwm]
        except MappingError as err:
            raise MappingError(f"{log.source}: servo_{ch.source}_pwm_us: {err}") from None
    return u


def initial_values(log: FlightLog, t0_s: float, forward_from_airspeed: bool) -> dict[str, float]:
    """The ``init_*`` parameters of our FMUs from the log at ``t0_s``.

    Attitude and body rates as logged, ``init_pos_down_m = -altitude``; body velocity from GPS NED velocity
    where logged, else the airspeed along body x (``forward_from_airspeed``, fixed wing) or rest.
    """
    at = np.array([t0_s])

    def val(name: str) -> float:
        return float(log.signal(name).resample(at)[0])

    roll, pitch = val("roll_rad"), val("pitch_rad")
    yaw = float(resample_angle(log.signal("yaw_rad"), at)[0])
    out = {"init_roll_rad": roll, "init_pitch_rad": pitch, "init_yaw_rad": yaw}
    for axis in "xyz":
        out[f"init_rate_body_{axis}_rad_s"] = val(f"gyro_body_{axis}_rad_s")
    if all(log.has(f"vel_{a}_m_s") for a in ("north", "east", "down")):
        v_ned = np.array([val(f"vel_{a}_m_s") for a in ("north", "east", "down")])
        r_b2n = np.asarray(ca.DM(quat_to_dcm(quat_from_euler(roll, pitch, yaw))))
        v_body = r_b2n.T @ v_ned
    elif forward_from_airspeed and log.has("airspeed_m_s"):
        v_body = np.array([val("airspeed_m_s"), 0.0, 0.0])
    else:
        v_body = np.zeros(3)
    for axis, v in zip("xyz", v_body, strict=True):
        out[f"init_vel_body_{axis}_m_s"] = float(v)
    if log.has("altitude_m"):
        out["init_pos_down_m"] = -val("altitude_m")
    return out
