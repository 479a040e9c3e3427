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
    read = start_signal_values(log, t_s, forward_from_airspeed)
    return [initial_values_from({n: float(v[i]) for n, v in read.items()}) for i in range(len(t_s))]


#: the logged signals a start state is read from (:func:`initial_values_from`), each optional but the attitude
#: and gyro; ``airspeed_m_s`` only where the GPS velocity is not logged and the forward speed comes from it
START_SIGNALS = ("roll_rad", "pitch_rad", "yaw_rad", "gyro_body_x_rad_s", "gyro_body_y_rad_s", "gyro_body_z_rad_s",
                 "vel_north_m_s", "vel_east_m_s", "vel_down_m_s", "airspeed_m_s", "altitude_m")


def start_signal_values(log: FlightLog, t_s: np.ndarray, forward_from_airspeed: bool) -> dict[str, np.ndarray]:
    """The :data:`START_SIGNALS` a start state at each time of ``t_s`` is read from, interpolated (yaw on its
    unwrapped series): the attitude and gyro always, the NED velocity where all three are logged, else the airspeed
    with ``forward_from_airspeed``, the altitude where logged."""
    out = {n: log.signal(n).resample(t_s) for n in ("roll_rad", "pitch_rad")}
    out["yaw_rad"] = resample_angle(log.signal("yaw_rad"), t_s)
    out.update({n: log.signal(n).resample(t_s) for n in START_SIGNALS[3:6]})
    if all(log.has(n) for n in START_SIGNALS[6:9]):
        out.update({n: log.signal(n).resample(t_s) for n in START_SIGNALS[6:9]})
    elif forward_from_airspeed and log.has("airspeed_m_s"):
        out["airspeed_m_s"] = log.signal("airspeed_m_s").resample(t_s)
    if log.has("altitude_m"):
        out["altitude_m"] = log.signal("altitude_m").resample(t_s)
    return out


def initial_values_from(v: dict[str, float]) -> dict[str, float]:
    """The ``init_*`` parameters from the logged values ``v`` at one instant (:func:`start_signal_values`): attitude
    and rates as logged, body velocity from the NED velocity rotated by the attitude where given, else the airspeed
    along body x, else rest; ``init_pos_down_m = -altitude`` where given."""
    d = {"init_roll_rad": v["roll_rad"], "init_pitch_rad": v["pitch_rad"], "init_yaw_rad": v["yaw_rad"]}
    for axis in "xyz":
        d[f"init_rate_body_{axis}_rad_s"] = v[f"gyro_body_{axis}_rad_s"]
    if "vel_north_m_s" in v:
        v_body = _euler_dcm(v["roll_rad"], v["pitch_rad"], v["yaw_rad"]).T @ np.array(
            [v["vel_north_m_s"], v["vel_east_m_s"], v["vel_down_m_s"]])
    elif "airspeed_m_s" in v:
        v_body = np.array([v["airspeed_m_s"], 0.0, 0.0])
    else:
        v_body = np.zeros(3)
    for axis, x in zip("xyz", v_body, strict=True):
        d[f"init_vel_body_{axis}_m_s"] = float(x)
    if "altitude_m" in v:
        d["init_pos_down_m"] = -float(v["altitude_m"])
    return d


#: fewest samples inside the windows for :func:`noise_std` to estimate a signal's noise
NOISE_MIN_SAMPLES = 20


def noise_std(sig: Signal, windows: Sequence[tuple[float, float]]) -> float:
    """The white measurement noise std of ``sig`` [its unit] inside ``windows`` ([t0, t1] s each): the
    median absolute second difference of consecutive samples over ``sqrt(6)`` x 0.6745 (a robust estimate:
    the second difference of white noise has variance 6 sigma^2, while a smooth motion sampled fast adds
    little to it, and a manoeuvre's few large steps do not move a median). Angles on their unwrapped series.
    0 with fewer than :data:`NOISE_MIN_SAMPLES` samples, or a signal held between samples (a median second
    difference of 0: no noise to read)."""
    vals = np.unwrap(sig.values) if sig.unit == "rad" else np.asarray(sig.values, float)
    d2 = []
    for t0, t1 in windows:
        sel = np.flatnonzero((sig.t_s >= t0) & (sig.t_s <= t1))
        if len(sel) >= 3:
            x = vals[sel]
            d2.append(x[2:] - 2.0 * x[1:-1] + x[:-2])
    d = np.concatenate(d2) if d2 else np.empty(0)
    d = d[np.isfinite(d)]
    if len(d) + 2 * len(d2) < NOISE_MIN_SAMPLES:
        return 0.0
    return float(np.median(np.abs(d)) / (0.6745 * np.sqrt(6.0)))


def interpolation_variance_factor(sig: Signal, t_s: float) -> float:
    """The variance of ``sig`` linearly interpolated at ``t_s`` over that of one sample, for white noise:
    ``(1 - w)^2 + w^2`` with ``w`` the weight of the later sample (1 on a sample, 1/2 midway)."""
    k = int(np.searchsorted(sig.t_s, t_s, side="right"))
    if k <= 0 or k >= len(sig.t_s):
        return 1.0
    a, b = float(sig.t_s[k - 1]), float(sig.t_s[k])
    w = (t_s - a) / (b - a) if b > a else 0.0
    return (1.0 - w) ** 2 + w ** 2


def _euler_dcm(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Body -> NED rotation of the 3-2-1 Euler angles [rad] (numpy floats: this runs once per replay window;
    ``fmu_models.common.rigid_body`` builds the same matrix symbolically for the models)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return np.array([[cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
                     [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
                     [-sp, sr * cp, cr * cp]])
