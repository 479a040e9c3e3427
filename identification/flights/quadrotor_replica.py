"""Synthetic quadrotor identification flights: a PX4-like closed loop flying planned stick inputs on the model.

The quadrotor model (``fmu_models.quadrotor``, the FMU's own equations through ``fmu_models.common.simulate``)
is stepped at ``sim_hz``; a cascaded controller like PX4's multicopter stack runs at ``rate_hz``: attitude P
(ALTCTL: roll/pitch sticks are angle setpoints, the yaw stick a yaw-rate setpoint, throttle a climb-rate
setpoint), rate PID on the gyro through a first-order low-pass (PX4 ``IMU_GYRO_CUTOFF``), D on a further
filtered rate (``IMU_DGYRO_CUTOFF``), a mixer built from the *nominal* airframe (the controller does not know
the truth) and the inverse of the thrust curve. The controller's PWM is held between its updates and logged at
``rate_hz`` (exactly what the motors get), with the gyro, accelerometer (white noise and a constant turn-on
bias), attitude, NED velocity, altitude and PX4's ``landed`` flag (never set: the flight starts in a hover), as a
:class:`FlightLog` in canonical signal names, and the excitation blocks as segments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from fmu_models.common.simulate import Simulator
from fmu_models.common.units import G0_M_S2
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.model import QuadrotorModel
from fmu_models.quadrotor.params import QuadrotorParams, motor_layout
from fmu_models.signals.names import OUTPUT_TO_LOG
from identification.flights.scenarios import published_thrust_inverse
from identification.flights.synthetic import multistep
from identification.logs.flightlog import FlightLog, Signal

#: white noise (1 sigma) of the logged sensors: gyro [rad/s], accelerometer [m/s2], attitude [rad], velocity [m/s]
GYRO_NOISE_RAD_S = 0.006
ACCEL_NOISE_M_S2 = 0.08
ATTITUDE_NOISE_RAD = 0.002
VELOCITY_NOISE_M_S = 0.03
#: largest turn-on bias of the accelerometer [m/s2] and gyro [rad/s] (drawn uniformly per flight)
ACCEL_BIAS_M_S2 = 0.15
GYRO_BIAS_RAD_S = 0.005
#: PX4 defaults: IMU_GYRO_CUTOFF 30 Hz (rate loop input), IMU_DGYRO_CUTOFF 30 Hz (D term)
GYRO_CUTOFF_HZ = 30.0
DGYRO_CUTOFF_HZ = 30.0
#: ALTCTL: full stick = MPC_MAN_TILT_MAX 35 deg; yaw stick = MPC_MAN_Y_MAX 150 deg/s; throttle = 3 m/s climb
MAX_TILT_RAD = math.radians(35.0)
MAX_YAW_RATE_RAD_S = math.radians(150.0)
MAX_CLIMB_M_S = 3.0


@dataclass(frozen=True)
class Block:
    """One planned stick input: axis ("roll", "pitch", "yaw", "throttle"), kind ("3211" or "doublet"),
    start [s], unit [s] and amplitude [stick, -1..1]; the block's segment runs from its start to ``end_s``."""

    axis: str
    kind: str
    start_s: float
    unit_s: float
    amplitude: float
    rest_s: float = 2.5

    @property
    def end_s(self) -> float:
        units = 7 if self.kind == "3211" else 2
        return self.start_s + units * self.unit_s + self.rest_s

    def stick(self, t: np.ndarray) -> np.ndarray:
        if self.kind == "3211":
            return multistep(t, self.start_s, self.unit_s, self.amplitude)
        out = np.zeros_like(t, dtype=float)
        out[(t >= self.start_s) & (t < self.start_s + self.unit_s)] = self.amplitude
        out[(t >= self.start_s + self.unit_s) & (t < self.start_s + 2 * self.unit_s)] = -self.amplitude
        return out


def planned_blocks(sets: int = 2, first_s: float = 3.0) -> list[Block]:
    """Stick 3-2-1-1s and doublets on roll, pitch and yaw and a throttle doublet, ``sets`` times (as the shared
    PX4 SITL flight: roll/pitch unit 0.25 s +-0.35, yaw unit 0.4 s +-0.5, doublets 2 x 0.3 s)."""
    out, t = [], first_s
    for k in range(sets):
        sign = 1.0 if k % 2 == 0 else -1.0
        for axis, kind, unit, amp in (("roll", "3211", 0.25, 0.35), ("pitch", "3211", 0.25, 0.35),
                                      ("yaw", "3211", 0.4, 0.5), ("roll", "doublet", 0.3, 0.35),
                                      ("pitch", "doublet", 0.3, 0.35), ("yaw", "doublet", 0.3, 0.5),
                                      ("throttle", "doublet", 0.6, 0.3)):
            b = Block(axis, kind, t, unit, sign * amp)
            out.append(b)
            t = b.end_s + 0.5
    return out


class _LowPass:
    """First-order low-pass at ``cutoff_hz`` sampled at ``dt_s`` (PX4 uses a biquad; the lag is alike)."""

    def __init__(self, cutoff_hz: float, dt_s: float, start: np.ndarray) -> None:
        self.a = 1.0 - math.exp(-2 * math.pi * cutoff_hz * dt_s)
        self.y = np.array(start, dtype=float)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self.y = self.y + self.a * (np.asarray(x, float) - self.y)
        return self.y


@dataclass
class ReplicaFlight:
    """A synthetic flight: the log, its excitation blocks, the truth it was flown with."""

    log: FlightLog
    blocks: list[Any]  #: :class:`Block`, or the blocks of the ``plan`` flown (``start_s``, ``end_s``, ``axis``)
    truth: QuadrotorParams


def fly_replica(truth: QuadrotorParams, blocks: list[Block] | None = None, rate_hz: float = 250.0,
                sim_hz: float = 1000.0, seed: int = 0, nominal: QuadrotorParams | None = None,
                altitude_m: float = 10.0, plan: Any = None) -> ReplicaFlight:
    """Fly ``truth`` through the planned ``blocks`` (default :func:`planned_blocks`) from a hover at
    ``altitude_m``; the controller is tuned on ``nominal`` (default: the F450 defaults). ``plan`` instead flies
    a stick plan of ``uavfmu excite --vehicle quadrotor`` (anything with ``sticks(t_s)`` -> N x 4 roll, pitch,
    yaw, throttle in -1..1 with the signs used here, ``duration_s`` and ``blocks`` with ``start_s``, ``end_s``,
    ``axis``)."""
    blocks = (planned_blocks() if blocks is None else blocks) if plan is None else list(plan.blocks)
    nom = nominal or QuadrotorParams()
    model = QuadrotorModel(truth)
    sim = Simulator(model)
    inv = published_thrust_inverse()
    hover_pwm = inv(truth.mass_kg * G0_M_S2 / N_MOTORS)
    p = sim.params(init_pos_down_m=-altitude_m)
    u = sim.inputs(**{f"pwm_{k}_us": hover_pwm for k in range(1, N_MOTORS + 1)})
    x, _ = sim.initial(u, p)
    rng = np.random.default_rng(seed)
    accel_bias = rng.uniform(-ACCEL_BIAS_M_S2, ACCEL_BIAS_M_S2, 3)
    gyro_bias = rng.uniform(-GYRO_BIAS_RAD_S, GYRO_BIAS_RAD_S, 3)
    duration = (max(b.end_s for b in blocks) if plan is None else float(plan.duration_s)) + 1.0
    n_ctrl = round(duration * rate_hz)
    sub = max(round(sim_hz / rate_hz), 1)
    dt_ctrl, dt_sim = 1.0 / rate_hz, 1.0 / (rate_hz * sub)
    t_ctrl = np.arange(n_ctrl) * dt_ctrl
    axes = ("roll", "pitch", "yaw", "throttle")
    if plan is None:
        sticks = {a: sum((b.stick(t_ctrl) for b in blocks if b.axis == a), np.zeros(n_ctrl)) for a in axes}
    else:
        planned = np.asarray(plan.sticks(t_ctrl), float)
        sticks = {a: np.clip(planned[:, i], -1.0, 1.0) for i, a in enumerate(axes)}
    gamma, spin = motor_layout(nom.frame)
    # mixer of the nominal airframe: [T_total, Mx, My, Mz] = A @ T_motors
    arm = nom.arm_length_m
    yaw_per_n = nom.b_drag_N_m_s2 / nom.k_thrust_N_s2
    A = np.array([[1.0] * N_MOTORS,
                  [-arm * math.sin(math.radians(g)) for g in gamma],
                  [arm * math.cos(math.radians(g)) for g in gamma],
                  [-s * yaw_per_n for s in spin]])
    A_inv = np.linalg.inv(A)
    J_nom = np.array([nom.Jx_kg_m2, nom.Jy_kg_m2, nom.Jz_kg_m2])
    kp_att, kp_yaw = np.array([6.5, 6.5]), 2.8
    kp_rate, ki_rate, kd_rate = np.array([18.0, 18.0, 10.0]), np.array([8.0, 8.0, 4.0]), np.array([0.25, 0.25, 0.0])
    rate_lp = _LowPass(GYRO_CUTOFF_HZ, dt_ctrl, np.zeros(3))
    drate_lp = _LowPass(DGYRO_CUTOFF_HZ, dt_ctrl, np.zeros(3))
    integ, prev_rate = np.zeros(3), np.zeros(3)
    yaw_sp, vz_int = None, 0.0
    idx = model.outputs.index
    cols = {c: np.empty(n_ctrl) for c in OUTPUT_TO_LOG.values() if c in (
        "roll_rad", "pitch_rad", "yaw_rad", "gyro_body_x_rad_s", "gyro_body_y_rad_s", "gyro_body_z_rad_s",
        "accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2", "altitude_m", "vel_north_m_s",
        "vel_east_m_s", "vel_down_m_s")}
    pwm_log = np.empty((n_ctrl, N_MOTORS))
    _, y = sim.initial(u, p)
    for k in range(n_ctrl):
        gyro = np.array([y[idx[f"rate_body_{a}_rad_s"]] for a in "xyz"])
        accel = np.array([y[idx[f"accel_body_{a}_m_s2"]] for a in "xyz"])
        roll, pitch, yaw = y[idx["roll_rad"]], y[idx["pitch_rad"]], y[idx["yaw_rad"]]
        meas_gyro = gyro + gyro_bias + rng.normal(0, GYRO_NOISE_RAD_S, 3)
        cols["gyro_body_x_rad_s"][k], cols["gyro_body_y_rad_s"][k], cols["gyro_body_z_rad_s"][k] = meas_gyro
        meas_acc = accel + accel_bias + rng.normal(0, ACCEL_NOISE_M_S2, 3)
        cols["accel_body_x_m_s2"][k], cols["accel_body_y_m_s2"][k], cols["accel_body_z_m_s2"][k] = meas_acc
        for name, v in (("roll_rad", roll), ("pitch_rad", pitch), ("yaw_rad", yaw)):
            cols[name][k] = v + rng.normal(0, ATTITUDE_NOISE_RAD)
        for name in ("vel_north_m_s", "vel_east_m_s", "vel_down_m_s"):
            cols[name][k] = y[idx[name]] + rng.normal(0, VELOCITY_NOISE_M_S)
        cols["altitude_m"][k] = y[idx["altitude_m"]]
        # ---- controller (PX4-like ALTCTL), on what the autopilot measures
        rate_f = rate_lp(meas_gyro)
        yaw_sp = yaw if yaw_sp is None else yaw_sp
        roll_sp, pitch_sp = sticks["roll"][k] * MAX_TILT_RAD, sticks["pitch"][k] * MAX_TILT_RAD
        yaw_rate_stick = sticks["yaw"][k] * MAX_YAW_RATE_RAD_S
        if abs(yaw_rate_stick) > 0:
            yaw_sp = yaw
        rate_sp = np.array([kp_att[0] * (roll_sp - roll), kp_att[1] * (pitch_sp - pitch),
                            yaw_rate_stick + kp_yaw * math.remainder(yaw_sp - yaw, 2 * math.pi)])
        err = rate_sp - rate_f
        integ = np.clip(integ + err * dt_ctrl, -0.3, 0.3)
        d_rate = drate_lp((rate_f - prev_rate) / dt_ctrl)
        prev_rate = rate_f
        alpha = kp_rate * err + ki_rate * integ - kd_rate * d_rate  # wanted angular acceleration [rad/s2]
        torque = J_nom * alpha
        vz_sp = -sticks["throttle"][k] * MAX_CLIMB_M_S
        vz_err = vz_sp - y[idx["vel_down_m_s"]]
        vz_int = float(np.clip(vz_int + vz_err * dt_ctrl, -3.0, 3.0))
        acc_down = 4.0 * vz_err + 1.0 * vz_int
        tilt = max(math.cos(roll) * math.cos(pitch), 0.5)
        total = nom.mass_kg * (G0_M_S2 - acc_down) / tilt
        thrust = np.clip(A_inv @ np.array([total, *torque]), 0.05, None)
        pwm = np.clip([inv(float(t)) for t in thrust], 1000.0, 2000.0)
        pwm_log[k] = pwm
        u[:N_MOTORS] = pwm
        for _ in range(sub):
            x, y = sim.step_arrays(x, u, p, dt_sim)
    signals = {n: Signal(n, t_ctrl.copy(), v, "", "replica") for n, v in cols.items()}
    # PX4's land detector (vehicle_land_detected.landed): airborne from the first sample, as the flight starts
    # in a hover
    signals["landed"] = Signal("landed", t_ctrl.copy(), np.zeros(n_ctrl), "", "replica")
    for m in range(N_MOTORS):
        for name in (f"motor_{m + 1}_pwm_us", f"servo_{m + 1}_pwm_us"):
            signals[name] = Signal(name, t_ctrl.copy(), pwm_log[:, m].copy(), "us", "replica")
    log = FlightLog(f"replica(seed={seed})", "synthetic", signals, {}, "quadrotor")
    return ReplicaFlight(log, blocks, truth)


def random_truth(rng: np.random.Generator, base: QuadrotorParams | None = None) -> QuadrotorParams:
    """A quadrotor unlike ``base`` (default F450): inertias +-40 %, motor time constant 0-50 ms, yaw torque
    constant and drag +-50 %."""
    import dataclasses

    b = base or QuadrotorParams()
    f = lambda lim: 1.0 + rng.uniform(-lim, lim)  # noqa: E731
    return dataclasses.replace(
        b, Jx_kg_m2=b.Jx_kg_m2 * f(0.4), Jy_kg_m2=b.Jy_kg_m2 * f(0.4), Jz_kg_m2=b.Jz_kg_m2 * f(0.4),
        tau_motor_s=float(rng.uniform(0.0, 0.05)), b_drag_N_m_s2=b.b_drag_N_m_s2 * f(0.5),
        kd_x_N_s_m=b.kd_x_N_s_m * f(0.5), kd_y_N_s_m=b.kd_y_N_s_m * f(0.5), kd_z_N_s_m=b.kd_z_N_s_m * f(0.5))
