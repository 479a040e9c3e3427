"""Scripted closed-loop flights of our FMUs through FMPy (as any importer would), recorded as arrays.

The demo uses them to make its own flight data: no external logs needed. The controllers are deliberately
plain cascaded PID loops, enough to fly a manoeuvre that excites what identification needs.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fmu_models.common.units import G0_M_S2
from fmu_models.fmi.host import FmuHost, FmuRunError
from fmu_models.quadrotor.constants import MASS_KG, N_MOTORS


@dataclass
class Recording:
    """Time series of one flight: FMU inputs and outputs by variable name."""

    t_s: np.ndarray
    inputs: dict[str, np.ndarray]
    outputs: dict[str, np.ndarray]
    start_values: dict[str, float] = field(default_factory=dict)


class FmuRunner:
    """One FMU instance (``fmu_models.fmi.host.FmuHost``) initialised with ``start_values``, stepped by name."""

    def __init__(self, fmu: Path, start_values: dict[str, float] | None = None) -> None:
        self.host = FmuHost(fmu, instance_name="scenario")
        self.outputs = [v.name for v in self.host.md.modelVariables if v.causality == "output" and v.type == "Real"]
        try:
            self.host.start(start_values)
        except FmuRunError:
            self.host.close()
            raise

    def __enter__(self) -> FmuRunner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.host.close()

    def read(self) -> dict[str, float]:
        return self.host.get(self.outputs)

    def step(self, t: float, h: float, inputs: dict[str, float]) -> dict[str, float]:
        self.host.step(t, h, inputs)
        return self.read()


def fly(fmu: Path, controller: Callable[[float, dict[str, float]], dict[str, float]], duration_s: float,
        dt_s: float = 0.01, start_values: dict[str, float] | None = None) -> Recording:
    """Fly ``fmu`` for ``duration_s`` with ``controller(t, outputs) -> inputs`` at ``dt_s``."""
    n = round(duration_s / dt_s)
    with FmuRunner(fmu, start_values) as run:
        y = run.read()
        ts, us, ys = [], [], []
        for k in range(n):
            t = k * dt_s
            u = controller(t, y)
            ts.append(t)
            us.append(u)
            ys.append(y)
            y = run.step(t, dt_s, u)
    return Recording(
        t_s=np.array(ts),
        inputs={k: np.array([u[k] for u in us]) for k in us[0]},
        outputs={k: np.array([y[k] for y in ys]) for k in ys[0]},
        start_values=dict(start_values or {}),
    )


@dataclass
class SampleHold:
    """Run ``controller`` every ``period_s`` and hold its command in between, like an autopilot's servo loop
    (outputs logged at that rate then reproduce the inputs exactly under zero-order hold)."""

    controller: Callable[[float, dict[str, float]], dict[str, float]]
    period_s: float
    _next_s: float = 0.0
    _held: dict[str, float] = field(default_factory=dict)

    def __call__(self, t: float, y: dict[str, float]) -> dict[str, float]:
        if not self._held or t >= self._next_s - 1e-9:
            self._held = self.controller(t, y)
            self._next_s = t + self.period_s
        return self._held


class ThrustInverse:
    """PWM per motor [us] for a wanted thrust per motor [N] on the rising envelope of a thrust curve.

    Where a map is not monotonic (the published one dips between 5800 and 5900 us summed), the lowest PWM
    reaching a thrust is used, so the controller never works on a branch where more PWM gives less thrust.
    """

    def __init__(self, thrust_per_motor_N: Callable[[np.ndarray], np.ndarray], lo_us: float = 1000.0,
                 hi_us: float = 2000.0) -> None:
        self.pwm_us = np.linspace(lo_us, hi_us, 4001)
        envelope = np.maximum.accumulate(thrust_per_motor_N(self.pwm_us))
        keep = np.concatenate([[True], np.diff(envelope) > 1e-9])
        self.pwm_us, self.thrust_N = self.pwm_us[keep], envelope[keep]

    def __call__(self, thrust_N: float) -> float:
        return float(np.interp(thrust_N, self.thrust_N, self.pwm_us))


def published_thrust_inverse() -> ThrustInverse:
    """Inverse of the default quadrotor's per-motor thrust (published map with its physical extension)."""
    from fmu_models.quadrotor.params import QuadrotorParams
    from fmu_models.quadrotor.thrust import thrust_sum

    p = QuadrotorParams()
    lo, hi = p.thrust_map.input_range[0]
    return ThrustInverse(lambda pwm: thrust_sum(p.thrust_map, 4 * pwm, 4 * p.pwm_idle_us, lo, hi) / 4)


@dataclass
class QuadrotorAutopilot:
    """Altitude, attitude and velocity loops mixed to Quad X PWM (motor order 1 FR, 2 RL, 3 FL, 4 RR).

    The altitude loop asks for a vertical acceleration, turned into thrust with the vehicle's mass and tilt
    and into PWM through the thrust curve's inverse; attitude loops add PWM differentials. ``altitude_m(t)``
    and ``yaw_rad(t)`` give the references; horizontal velocity is held at zero.
    """

    altitude_m: Callable[[float], float]
    thrust_inverse: ThrustInverse
    mass_kg: float = MASS_KG
    gravity_m_s2: float = G0_M_S2
    kp_alt: float = 1.2
    kd_alt: float = 1.8
    ki_alt: float = 0.15
    kp_att: float = 5.0
    kp_rate: float = 12.0
    kp_yaw: float = 2.0
    kp_yaw_rate: float = 40.0
    kp_vel: float = 0.08
    yaw_rad: Callable[[float], float] = lambda t: 0.0
    integral: float = 0.0  #: altitude error integral [m s] (controller state)
    last_t: float = 0.0  #: time of the previous call [s]

    def __call__(self, t: float, y: dict[str, float]) -> dict[str, float]:
        dt = max(t - self.last_t, 0.0)
        self.last_t = t
        alt_err = self.altitude_m(t) - y["altitude_m"]
        self.integral = min(max(self.integral + alt_err * dt, -10.0), 10.0)
        climb_m_s = -y["vel_down_m_s"]
        accel_up = self.kp_alt * alt_err - self.kd_alt * climb_m_s + self.ki_alt * self.integral
        accel_up = min(max(accel_up, -4.0), 4.0)
        tilt = max(math.cos(y["roll_rad"]) * math.cos(y["pitch_rad"]), 0.5)
        base = self.thrust_inverse(self.mass_kg * (self.gravity_m_s2 + accel_up) / tilt / N_MOTORS)
        # hold horizontal velocity at zero: body-frame velocity error -> attitude reference
        roll_ref = max(min(-self.kp_vel * y["vel_body_y_m_s"], 0.3), -0.3)
        pitch_ref = max(min(self.kp_vel * y["vel_body_x_m_s"], 0.3), -0.3)
        roll_cmd = self.kp_rate * (self.kp_att * (roll_ref - y["roll_rad"]) - y["rate_body_x_rad_s"])
        pitch_cmd = self.kp_rate * (self.kp_att * (pitch_ref - y["pitch_rad"]) - y["rate_body_y_rad_s"])
        yaw_err = math.remainder(self.yaw_rad(t) - y["yaw_rad"], 2 * math.pi)
        yaw_cmd = self.kp_yaw_rate * (self.kp_yaw * yaw_err - y["rate_body_z_rad_s"])
        pwm = [
            base - roll_cmd + pitch_cmd + yaw_cmd,  # 1 front-right CCW
            base + roll_cmd - pitch_cmd + yaw_cmd,  # 2 rear-left CCW
            base + roll_cmd + pitch_cmd - yaw_cmd,  # 3 front-left CW
            base - roll_cmd - pitch_cmd - yaw_cmd,  # 4 rear-right CW
        ]
        return {f"pwm_{i + 1}_us": min(max(p, 1000.0), 2000.0) for i, p in enumerate(pwm)}


def quadrotor_profile(t: float) -> float:
    """Altitude reference [m] of the demo flight: climb, hover, a staircase up and down, land-ish."""
    steps = [(0.0, 0.0), (2.0, 10.0), (15.0, 14.0), (22.0, 6.0), (29.0, 12.0), (36.0, 3.0), (43.0, 10.0)]
    ref = 0.0
    for t0, h in steps:
        if t >= t0:
            ref = h
    return ref


@dataclass
class FixedWingAutopilot:
    """Bank-angle, pitch/altitude, yaw-damper and airspeed loops around a trim (Beard & McLain sign conventions:
    positive aileron rolls right, positive elevator pitches nose down, positive rudder yaws left).

    ``bank_rad(t)`` is the bank reference; ``aileron_excitation(t)`` is added to the aileron command (3-2-1-1
    inputs for identification ride on top of the closed loop, as in flight test).
    """

    trim_inputs: dict[str, float]
    trim_pitch_rad: float
    bank_rad: Callable[[float], float]
    aileron_excitation: Callable[[float], float] = lambda t: 0.0
    altitude_m: float = 100.0
    airspeed_m_s: float = 25.0
    k_bank: float = 0.6
    k_roll_rate: float = 0.08
    k_pitch: float = 1.5
    k_pitch_rate: float = 0.15
    k_alt: float = 0.02
    k_yaw_damper: float = 0.3
    k_airspeed: float = 0.05

    def __call__(self, t: float, y: dict[str, float]) -> dict[str, float]:
        u = self.trim_inputs
        pitch_ref = self.trim_pitch_rad + max(min(self.k_alt * (self.altitude_m - y["altitude_m"]), 0.15), -0.15)
        aileron = (u["aileron_rad"] + self.k_bank * (self.bank_rad(t) - y["roll_rad"])
                   - self.k_roll_rate * y["rate_body_x_rad_s"] + self.aileron_excitation(t))
        elevator = (u["elevator_rad"] - self.k_pitch * (pitch_ref - y["pitch_rad"])
                    + self.k_pitch_rate * y["rate_body_y_rad_s"])
        rudder = u["rudder_rad"] + self.k_yaw_damper * y["rate_body_z_rad_s"]
        throttle = u["throttle"] + self.k_airspeed * (self.airspeed_m_s - y["airspeed_m_s"])
        lim = 0.35
        return {"aileron_rad": min(max(aileron, -lim), lim), "elevator_rad": min(max(elevator, -lim), lim),
                "rudder_rad": min(max(rudder, -lim), lim), "throttle": min(max(throttle, 0.0), 1.0)}


def fixed_wing_bank_profile(t: float) -> float:
    """Bank reference [rad] of the demo flight: level, 25 deg right, 25 deg left, level, repeated every 40 s."""
    tt = t % 40.0
    return math.radians(25.0) if 5 <= tt < 12 else math.radians(-25.0) if 17 <= tt < 24 else 0.0


def fixed_wing_excitation(t: float) -> float:
    """Aileron 3-2-1-1 multisteps [rad] at 1, 13 and 27 s of every 40 s block (0.4 s unit, 0.04 rad)."""
    tt = t % 40.0
    out = 0.0
    for t0 in (1.0, 13.0, 27.0):
        k = (tt - t0) / 0.4
        if 0 <= k < 7:
            out = 0.04 * (1 if k < 3 else -1 if k < 5 else 1 if k < 6 else -1)
    return out


def fixed_wing_start(params: Any = None, airspeed_m_s: float = 25.0, altitude_m: float = 100.0
                     ) -> tuple[dict[str, float], dict[str, float], float]:
    """Start values (trimmed state at ``altitude_m``), trim inputs and trim pitch [rad] of the fixed wing."""
    from fmu_models.common.rigid_body import euler_from_quat
    from fmu_models.common.simulate import Simulator
    from fmu_models.fixed_wing.model import FixedWingModel
    from fmu_models.fixed_wing.trim import trim

    sim = Simulator(FixedWingModel(params))
    tr = trim(sim.model, sim.params(), airspeed_m_s)
    pitch = float(np.asarray(euler_from_quat(tr.x[6:10])).ravel()[1])
    inputs = {n: float(tr.u[i]) for n, i in sim.model.inputs.index.items()}
    start = {"init_pos_down_m": -altitude_m, "init_vel_body_x_m_s": float(tr.x[3]),
             "init_vel_body_z_m_s": float(tr.x[5]), "init_pitch_rad": pitch, **inputs}
    return start, inputs, pitch
