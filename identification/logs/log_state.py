"""What replay and identification take from a log: input samples and the vehicle's state at an instant."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from fmu_models.common.mathns import NP
from fmu_models.common.rotations import euler_to_dcm_rows, transpose_apply
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.signals.pwm_mapping import MappingError, PwmMapping
from identification.logs.flightlog import FlightLog, Signal


def resample_angle(sig: Signal, t_s: np.ndarray) -> np.ndarray:
    """An angle [rad] at ``t_s``, interpolated on the unwrapped series (logs wrap yaw at 0/360 deg: plain
    interpolation across the wrap gives 180 deg), wrapped back to (-pi, pi]."""
    unwrapped = np.interp(t_s, sig.t_s, np.unwrap(sig.values))
    return np.angle(np.exp(1j * unwrapped))


def unwrapped_angle(sig: Signal, t_s: np.ndarray) -> np.ndarray:
    """An angle [rad] at ``t_s`` as one continuous series (no jump at the +-180 deg seam): differences of it
    are true angular changes, so baselines and metrics need no special case."""
    return np.interp(t_s, sig.t_s, np.unwrap(sig.values))


#: what :func:`body_velocity` reads: the logged attitude [rad] and NED velocity [m/s]
BODY_VELOCITY_SIGNALS = ("roll_rad", "pitch_rad", "yaw_rad", "vel_north_m_s", "vel_east_m_s", "vel_down_m_s")


def body_velocity(series: dict[str, tuple[np.ndarray, np.ndarray]], t_s: np.ndarray) -> np.ndarray:
    """The logged NED velocity rotated into the body by the logged attitude at ``t_s`` (len x 3, body x, y, z)
    [m/s]. ``series`` maps each of :data:`BODY_VELOCITY_SIGNALS` to ``(t_s, values)``; the angles are interpolated
    on their unwrapped series (across yaw's +-pi seam a plain interpolation turns the velocity)."""
    val = {n: np.interp(t_s, series[n][0], np.unwrap(series[n][1]) if n.endswith("_rad") else series[n][1])
           for n in BODY_VELOCITY_SIGNALS}
    rows = euler_to_dcm_rows(val["roll_rad"], val["pitch_rad"], val["yaw_rad"], NP)
    return np.column_stack(transpose_apply(rows, [val["vel_north_m_s"], val["vel_east_m_s"], val["vel_down_m_s"]]))


#: a quadrotor's motors count as idle up to this far above the idle PWM (ArduCopter spins them at
#: MOT_SPIN_ARMED, ~1060-1150 us, while armed on the ground)
IDLE_MARGIN_US = 50.0
#: heights above the ground level [m] below which the vehicle counts as on the ground
GROUND_HEIGHT_M = {"quadrotor": 0.3, "fixed_wing": 1.0}
#: a multirotor log that starts at its lowest altitude and later rises more than this [m] starts on the ground
TAKEOFF_RISE_M = 1.0
#: a fixed wing below this airspeed [m/s] is taxiing or parked
WING_GROUND_AIRSPEED_M_S = 8.0


def parked_samples(log: FlightLog, vehicle: str, t_s: np.ndarray, idle_pwm_us: float) -> dict[str, np.ndarray]:
    """Samples of ``t_s`` where the vehicle is parked, by criterion (plain-words name -> bool mask): the log's
    ``landed`` flag where logged; quadrotor motors all at idle (at most ``idle_pwm_us`` + ``IDLE_MARGIN_US``);
    fixed wing below ``WING_GROUND_AIRSPEED_M_S``. The samples the ground level is taken over."""
    out: dict[str, np.ndarray] = {}
    if log.has("landed"):
        out["landed flag set"] = hold(log.signal("landed"), t_s) > 0.5
    if vehicle == "quadrotor":
        pwm = np.max([hold(log.signal(f"motor_{k}_pwm_us"), t_s) for k in range(1, N_MOTORS + 1)], axis=0)
        out[f"motors at idle (<= {idle_pwm_us + IDLE_MARGIN_US:g} us)"] = pwm <= idle_pwm_us + IDLE_MARGIN_US
    elif log.has("airspeed_m_s"):
        out[f"airspeed below {WING_GROUND_AIRSPEED_M_S:g} m/s"] = \
            log.signal("airspeed_m_s").resample(t_s) < WING_GROUND_AIRSPEED_M_S
    return out


def any_of(masks: dict[str, np.ndarray], n: int) -> np.ndarray:
    """Samples where any of ``masks`` holds (none: no sample of ``n``)."""
    return np.any(list(masks.values()), axis=0) if masks else np.zeros(n, dtype=bool)


def ground_samples(log: FlightLog, vehicle: str, t_s: np.ndarray, idle_pwm_us: float) -> dict[str, np.ndarray]:
    """Samples of ``t_s`` where the vehicle is on the ground, by criterion (plain-words name -> bool mask).

    Criteria: those of :func:`parked_samples`; height above the ground level below ``GROUND_HEIGHT_M``, the
    ground level being that of :func:`ground_level`; without one, no height criterion.
    """
    out = parked_samples(log, vehicle, t_s, idle_pwm_us)
    level = ground_level(log, vehicle, t_s, any_of(out, len(t_s)))
    if level is not None:
        limit = GROUND_HEIGHT_M.get(vehicle, 0.3)
        out[f"below {limit:g} m above the ground level"] = log.signal("altitude_m").resample(t_s) - level < limit
    return out


def ground_level(log: FlightLog, vehicle: str, t_s: np.ndarray, parked: np.ndarray) -> float | None:
    """The log's ground level [m, its altitude scale]: the median altitude over the ``parked`` samples of
    ``t_s``; else, for a multirotor log without a ``landed`` flag, the first altitude of a log that takes off
    (:func:`takes_off`: a take-off with no idle phase logged); None without altitude or such evidence. A log
    whose ``landed`` flag is logged and never set was airborne throughout (a log started in flight): no
    ground level is guessed from its altitude."""
    if not (log.has("altitude_m") and len(t_s)):
        return None
    alt = log.signal("altitude_m").resample(t_s)
    if parked.any():
        return float(np.median(alt[parked]))
    if vehicle == "quadrotor" and not log.has("landed") and takes_off(alt):
        return float(alt[0])
    return None


def takes_off(alt_m: np.ndarray) -> bool:
    """Whether an altitude series [m] is a multirotor's take-off with no idle phase logged: it starts at its
    lowest point (within ``GROUND_HEIGHT_M``) and, the first time it leaves that band, climbs on to more than
    ``TAKEOFF_RISE_M`` above its start before it comes back into the band. A log started in a hover that bobs
    out of the band and back (a throttle input) is not one: ground does not rise and fall back under a
    vehicle; a hover start that climbs straight away cannot be told from a take-off without a ``landed`` flag."""
    alt = np.asarray(alt_m, dtype=float)
    band = GROUND_HEIGHT_M["quadrotor"]
    if not len(alt) or alt[0] - np.nanmin(alt) >= band:
        return False
    above = np.flatnonzero(alt - alt[0] >= band)
    if not len(above):
        return False
    back = np.flatnonzero(alt[above[0]:] - alt[0] < band)
    climb = alt[above[0]:above[0] + back[0]] if len(back) else alt[above[0]:]
    return bool(np.nanmax(climb) - alt[0] > TAKEOFF_RISE_M)


#: a log sample within this much after a query time counts as at it [s]: half the 1 us resolution of log time
#: stamps, so that a query on a sample's time (a grid plus a whole-sample delay) is not lost to rounding
HOLD_TOLERANCE_S = 5e-7


def hold(sig: Signal, t_s: np.ndarray) -> np.ndarray:
    """Zero-order hold of ``sig`` at ``t_s``: commanded outputs (servo PWM) hold between log samples."""
    idx = np.clip(np.searchsorted(sig.t_s, np.asarray(t_s) + HOLD_TOLERANCE_S, side="right") - 1, 0,
                  len(sig.t_s) - 1)
    return sig.values[idx]


def mapped_inputs(names: Sequence[str], log: FlightLog, mapping: PwmMapping, t_s: np.ndarray,
                  sample: Callable[[Signal, np.ndarray], np.ndarray] = hold) -> np.ndarray:
    """FMU/model inputs ``names`` (len(t) x len(names)) from the log's servo PWM through ``mapping``; ``sample``
    reads a PWM signal at ``t_s`` (default: zero-order hold)."""
    by_target = {c.target: c for c in mapping.channels}
    missing = [n for n in names if n not in by_target]
    if missing:
        raise MappingError(f"the PWM mapping has no channel for the inputs {', '.join(missing)}")
    u = np.empty((len(t_s), len(names)))
    for i, name in enumerate(names):
        ch = by_target[name]
        pwm = sample(log.signal(f"servo_{ch.source}_pwm_us"), t_s)
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
    return initial_values_at(log, np.array([t0_s]), forward_from_airspeed)[0]


def initial_values_at(log: FlightLog, t_s: np.ndarray, forward_from_airspeed: bool) -> list[dict[str, float]]:
    """:func:`initial_values` at every time of ``t_s``, each signal resampled once for all of them."""
    t_s = np.asarray(t_s, dtype=float)

    def val(name: str) -> np.ndarray:
        return log.signal(name).resample(t_s)

    roll, pitch = val("roll_rad"), val("pitch_rad")
    yaw = resample_angle(log.signal("yaw_rad"), t_s)
    rates = [val(f"gyro_body_{axis}_rad_s") for axis in "xyz"]
    has_gps_vel = all(log.has(f"vel_{a}_m_s") for a in ("north", "east", "down"))
    v_ned = np.column_stack([val(f"vel_{a}_m_s") for a in ("north", "east", "down")]) if has_gps_vel else None
    airspeed = val("airspeed_m_s") if forward_from_airspeed and log.has("airspeed_m_s") else None
    altitude = val("altitude_m") if log.has("altitude_m") else None
    out = []
    for i in range(len(t_s)):
        d = {"init_roll_rad": float(roll[i]), "init_pitch_rad": float(pitch[i]), "init_yaw_rad": float(yaw[i])}
        for axis, r in zip("xyz", rates, strict=True):
            d[f"init_rate_body_{axis}_rad_s"] = float(r[i])
        if v_ned is not None:
            v_body = _euler_dcm(roll[i], pitch[i], yaw[i]).T @ v_ned[i]
        elif airspeed is not None:
            v_body = np.array([airspeed[i], 0.0, 0.0])
        else:
            v_body = np.zeros(3)
        for axis, v in zip("xyz", v_body, strict=True):
            d[f"init_vel_body_{axis}_m_s"] = float(v)
        if altitude is not None:
            d["init_pos_down_m"] = -float(altitude[i])
        out.append(d)
    return out


def _euler_dcm(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Body -> NED rotation of the 3-2-1 Euler angles [rad] (numpy floats: this runs once per replay window;
    ``fmu_models.common.rigid_body`` builds the same matrix symbolically for the models)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return np.array([[cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
                     [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
                     [-sp, sr * cp, cr * cp]])
