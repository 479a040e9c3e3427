"""Quadrotor forces, moments and state equations (paper 000 eqs. 5-10 on the shared 6-DOF body).

Frames: NED world, FRD body (paper 000 writes thrust along +z of a z-up body; here it acts along -z).
Forces (body): thrust ``(0, 0, -sum T_i)`` (eq. 6), linear drag ``-kd * v_body`` (eq. 7), ground contact.
Moments (body): arm moments ``sum r_i x (0, 0, -T_i) = (-l sin(g_i) T_i, l cos(g_i) T_i, 0)`` (eq. 8, FRD),
gyroscopic ``-omega x h_rotors`` with ``h_rotors = (0, 0, sum J_m s_i Omega_i)`` (eq. 9), fan torque
``(0, 0, -sum s_i b Omega_i^2)`` (eq. 10) with spin s_i = +1 clockwise seen from above.
Thrust: per motor ``T_i = ANFIS(n * pwm_i) / n`` - the map was trained on the sum of n equal-ish PWMs, so
a motor commanded ``pwm_i`` makes 1/n of what the whole vehicle makes with every motor at ``pwm_i``.
``Omega_i = sqrt(T_i / k)`` feeds the gyroscopic and fan terms. An optional first-order lag with time
constant ``tau_motor_s`` acts on each motor's thrust.
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca

from fmu_models.common import vehicle
from fmu_models.common.ground import contact_forces
from fmu_models.common.mathns import CA as _CA
from fmu_models.common.model import Variable
from fmu_models.common.rigid_body import inertia_matrix
from fmu_models.quadrotor.anfis import AnfisMap
from fmu_models.quadrotor.constants import INIT_THRUST_NAMES, N_MOTORS
from fmu_models.quadrotor.params import QuadrotorParams, motor_layout
from fmu_models.quadrotor.thrust import (
    constants_of,
    map_from_params,
    map_param_variables,
    motor_out_of_band,
    motor_thrust,
)

PWM_INPUT_MIN_US = 0.0  #: 0 us = no pulse (motor off); below idle thrust is zero anyway
PWM_INPUT_MAX_US = 2500.0
#: initial motor-lag states [N]: a restart in the middle of a manoeuvre (a replay window) starts each motor at the
#: thrust it lags at there, not at the thrust its PWM commands (negative: the commanded thrust, a start at rest)
INIT_THRUST_PARAMS: tuple[Variable, ...] = tuple(
    Variable(name, "N", f"initial thrust of motor {i} (lag state; negative: at the commanded thrust)",
             -1.0, -1.0, 1000.0) for i, name in enumerate(INIT_THRUST_NAMES, start=1))
OMEGA_EPS_N = 1e-6  #: below this thrust [N] the motor speed goes linearly to 0 (finite derivative at idle)


def _n_inputs(u: Any) -> int:
    """Length of an input vector (CasADi or numeric); callers may leave out the trailing voltage."""
    return int(u.numel()) if hasattr(u, "numel") else len(u)


class QuadrotorModel(vehicle.BodyVehicleModel):
    """Quadrotor of paper 000 as a ``VehicleModel`` (see ``fmu_models.common.model``)."""

    name = "quadrotor"
    description = ("Quadrotor 6-DOF (Sant'Ana et al. COBEM 2019): ANFIS thrust map of summed motor PWM, linear drag, "
                   "arm, gyroscopic and fan moments; WGS-84 gravity and geodetic position; ground contact.")

    def __init__(self, params: QuadrotorParams | None = None) -> None:
        defaults = params or QuadrotorParams()
        self.gamma_deg, self.spin = motor_layout(defaults.frame)
        inputs = (
            *(Variable(f"pwm_{i}_us", "us", f"motor {i} PWM command", 1000.0, PWM_INPUT_MIN_US, PWM_INPUT_MAX_US)
              for i in range(1, N_MOTORS + 1)),
            Variable("battery_voltage_V", "V",
                     "battery voltage (thrust per PWM grows with it; start: battery_nominal_V of the build)",
                     defaults.battery_nominal_V, 0.0, 100.0),
        )
        outputs = (
            *(Variable(f"thrust_{i}_N", "N", f"motor {i} thrust") for i in range(1, N_MOTORS + 1)),
            Variable("thrust_total_N", "N", "total thrust along -z body"),
            *(Variable(f"omega_{i}_rad_s", "rad/s", f"motor {i} speed") for i in range(1, N_MOTORS + 1)),
            Variable("thrust_map_out_of_range", "", "a motor's PWM x 4 lies outside the thrust map's trained band",
                     boolean=True),
        )
        super().__init__(
            defaults, inputs,
            states=tuple(Variable(f"thrust_state_{i}_N", "N", f"motor {i} thrust (lag state)")
                         for i in range(1, N_MOTORS + 1)),
            state_limits=(1e4,) * N_MOTORS,
            params=(*map_param_variables(defaults.thrust_map), *INIT_THRUST_PARAMS),
            outputs=outputs,
        )
        self.gear_points = self._gear_points()

    def structure_key(self) -> str | None:
        """Built from its parameter defaults alone (``BodyVehicleModel.structure_key``)."""
        return super().structure_key()

    def _gear_points(self) -> list[tuple[float, float, float]]:
        """Four landing-gear points under the arms, at CG height (the NED origin is the landed CG)."""
        r = 0.6 * self.defaults.arm_length_m
        return [
            (r * math.cos(math.radians(g)), r * math.sin(math.radians(g)), 0.0)
            for g in (45.0, 135.0, 225.0, 315.0)
        ]

    # ------------------------------------------------------------------ pieces
    def _map(self, pv: Any) -> AnfisMap:
        """The thrust map with its values taken from the parameter vector (symbolic in code generation)."""
        return map_from_params(self.defaults.thrust_map, pv)

    def commanded_thrust(self, u: Any, p: Any) -> list[Any]:
        """Per-motor thrust [N] the map gives for the PWM inputs (before the motor lag)."""
        pv = self.params.view(p)
        amap = self._map(pv)
        c = constants_of(pv, self.defaults.thrust_map)
        volt = u[N_MOTORS] if _n_inputs(u) > N_MOTORS else pv.battery_nominal_V
        return [motor_thrust(amap, u[i], volt, c, N_MOTORS, _CA) for i in range(N_MOTORS)]

    def out_of_range(self, u: Any, p: Any) -> Any:
        pv = self.params.view(p)
        c = constants_of(pv, self.defaults.thrust_map)
        volt = u[N_MOTORS] if _n_inputs(u) > N_MOTORS else pv.battery_nominal_V
        flag = 0.0
        for i in range(N_MOTORS):  # at or below idle the thrust is simply 0: not out of band
            flag = ca.fmax(flag, motor_out_of_band(self.defaults.thrust_map, u[i], volt, c, N_MOTORS, _CA))
        return flag

    def motor_thrust(self, x: Any, u: Any, p: Any) -> list[Any]:
        """Thrust [N] acting now: the lag states, or the commanded thrust when there is no lag."""
        pv = self.params.view(p)
        cmd = self.commanded_thrust(u, p)
        return [ca.if_else(pv.tau_motor_s > 0, x[16 + i], cmd[i]) for i in range(N_MOTORS)]

    def forces_moments(self, x: Any, u: Any, p: Any) -> tuple[Any, Any, dict[str, Any]]:
        """Non-gravitational force [N] and moment [N m] in body axes, and intermediate values."""
        pv = self.params.view(p)
        _, vel, quat, rates, _ = vehicle.split(x)
        thrust = self.motor_thrust(x, u, p)
        # sqrt(T/k), written T / sqrt(k max(T, eps)): the same above eps, linear to 0 below, so its derivative
        # stays finite at zero thrust (output-error sensitivities would otherwise turn NaN at an idle motor)
        omega = [ca.fmax(t, 0.0) / ca.sqrt(pv.k_thrust_N_s2 * ca.fmax(t, OMEGA_EPS_N)) for t in thrust]
        total = thrust[0] + thrust[1] + thrust[2] + thrust[3]
        drag = -ca.vertcat(pv.kd_x_N_s_m * vel[0], pv.kd_y_N_s_m * vel[1], pv.kd_z_N_s_m * vel[2])
        f_ground, m_ground, on_ground = contact_forces(
            x[0:3], vel, quat, rates, self.gear_points, pv.mass_kg, pv.ground_wn_rad_s, pv.ground_zeta,
            pv.ground_mu, pv.ground_mu,
        )
        force = ca.vertcat(0, 0, -total) + drag + f_ground
        l_arm = pv.arm_length_m
        m_arm_x = 0
        m_arm_y = 0
        h_rotor = 0
        m_fan = 0
        for i in range(N_MOTORS):
            g = math.radians(self.gamma_deg[i])
            m_arm_x = m_arm_x - l_arm * math.sin(g) * thrust[i]
            m_arm_y = m_arm_y + l_arm * math.cos(g) * thrust[i]
            h_rotor = h_rotor + pv.J_rotor_kg_m2 * self.spin[i] * omega[i]
            m_fan = m_fan - self.spin[i] * pv.b_drag_N_m_s2 * omega[i] ** 2
        m_gyro = ca.vertcat(-rates[1] * h_rotor, rates[0] * h_rotor, 0)
        moment = ca.vertcat(m_arm_x, m_arm_y, m_fan) + m_gyro + m_ground
        extras = {"thrust": thrust, "omega": omega, "total": total, "on_ground": on_ground}
        return force, moment, extras

    # ------------------------------------------------------------------ VehicleModel
    def inertia(self, p: Any) -> Any:
        pv = self.params.view(p)
        return inertia_matrix(pv.Jx_kg_m2, pv.Jy_kg_m2, pv.Jz_kg_m2, 0.0)

    def derivatives(self, t: Any, x: Any, u: Any, p: Any) -> Any:
        """State derivative: 16 body states (shared 6-DOF) and 4 motor-lag states."""
        pv = self.params.view(p)
        body = self.body_derivatives(x, u, p)
        cmd = self.commanded_thrust(u, p)
        lag = [
            ca.if_else(pv.tau_motor_s > 0, (cmd[i] - x[16 + i]) / ca.fmax(pv.tau_motor_s, 1e-9), 0.0)
            for i in range(N_MOTORS)
        ]
        return ca.vertcat(body, *lag)

    def outputs_fn(self, x: Any, u: Any, p: Any) -> Any:
        nav, ex = self.nav_outputs(x, u, p)
        return ca.vertcat(*nav, *ex["thrust"], ex["total"], *ex["omega"], self.out_of_range(u, p))

    def initial_state(self, p: Any, u: Any) -> Any:
        """Initial state from the ``init_*``/``home_*`` parameters; each motor lag at ``init_thrust_<i>_N`` when
        that is not negative, else at the commanded thrust of the first input."""
        pv = self.params.view(p)
        cmd = self.commanded_thrust(u, p)
        lag = [ca.if_else(getattr(pv, f"init_thrust_{i + 1}_N") >= 0, getattr(pv, f"init_thrust_{i + 1}_N"), cmd[i])
               for i in range(N_MOTORS)]
        return ca.vertcat(vehicle.initial_body_state(pv), *lag)

    def post_step(self, x: Any, u: Any, p: Any) -> Any:
        """Renormalise the quaternion; without a motor lag, keep the lag states equal to the command."""
        pv = self.params.view(p)
        xn = vehicle.normalize_quaternion(x)
        cmd = self.commanded_thrust(u, p)
        lag = [ca.if_else(pv.tau_motor_s > 0, xn[16 + i], cmd[i]) for i in range(N_MOTORS)]
        return ca.vertcat(xn[0:16], *lag)
