"""Fixed-wing forces, moments and state equations (paper 001; Beard & McLain ch. 4 Aerosonde model).

Frames: NED world, FRD body; stability-axis lift and drag rotated into body axes by alpha.
Air-relative velocity ``v_r = v_body - R^T wind_ned``; ``Va = |v_r|``, ``alpha = atan2(w_r, u_r)``,
``beta = asin(v_r / Va)``. Coefficients (dynamic pressure ``qbar = rho Va^2 / 2``):
``C_L(alpha) = (1 - s) (C_L_0 + C_L_alpha alpha) + s 2 sign(alpha) sin^2(alpha) cos(alpha)`` with the
sigmoid ``s`` of sharpness ``M_blend`` around ``alpha0_rad``; ``C_D(alpha) = C_D_p + (C_L_0 + C_L_alpha
alpha)^2 / (pi e AR)``; pitch, roll, yaw and side force as sums of stability and control derivatives
(rates non-dimensionalised by ``c / 2Va`` or ``b / 2Va``). Propeller: motor speed from the torque balance of
the DC motor and the propeller (quadratic in Omega), thrust and torque from ``C_T(J)``, ``C_Q(J)``; the roll
moment includes minus the propeller torque. Aerodynamic forces act at the aerodynamic centre ``x_ac_m``
ahead of the CG, so they add ``r_ac x F_aero`` to the moments.
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca

from fmu_models.common import vehicle
from fmu_models.common.atmosphere import isa
from fmu_models.common.ground import contact_forces
from fmu_models.common.model import Variable
from fmu_models.common.rigid_body import inertia_matrix, quat_to_dcm
from fmu_models.fixed_wing.params import FixedWingParams

SURFACE_LIMIT_RAD = math.radians(45.0)
VA_EPS_M_S = 1e-3  #: keeps Va, beta and their derivatives finite at rest; changes Va by < 1e-8 in flight

#: Tricycle gear (body FRD, m): nose wheel ahead of the CG, mains behind it, at CG height.
GEAR_POINTS = [(0.6, 0.0, 0.0), (-0.15, -0.5, 0.0), (-0.15, 0.5, 0.0)]


class FixedWingModel(vehicle.BodyVehicleModel):
    """Aerosonde-type fixed wing as a ``VehicleModel`` (see ``fmu_models.common.model``)."""

    name = "fixed_wing"
    description = ("Fixed-wing 6-DOF (Manai et al.; Beard & McLain Aerosonde): stability and control derivatives, "
                   "propeller and DC motor, constant wind, WGS-84 gravity and geodetic position, ground contact.")

    def __init__(self, params: FixedWingParams | None = None) -> None:
        surface = (0.0, -SURFACE_LIMIT_RAD, SURFACE_LIMIT_RAD)
        inputs = (
            Variable("aileron_rad", "rad", "aileron deflection, uavbook sign: positive rolls right "
                     "(C_ell_delta_a > 0; autopilot PWM above trim)", *surface),
            Variable("elevator_rad", "rad", "elevator deflection, uavbook sign: positive is trailing edge down, "
                     "nose down (C_m_delta_e < 0; autopilot pull = PWM above trim = negative)", *surface),
            Variable("rudder_rad", "rad", "rudder deflection, uavbook sign: positive is trailing edge left, "
                     "nose left (C_n_delta_r < 0; autopilot right rudder = PWM above trim = negative)", *surface),
            Variable("throttle", "1", "throttle fraction, 0 = motor off, 1 = full (PWM min..max)", 0.0, 0.0, 1.0),
        )
        outputs = (
            Variable("airspeed_m_s", "m/s", "true airspeed Va"),
            Variable("airspeed_body_x_m_s", "m/s", "airspeed along body x (paper 001 Table 1, v_ax)"),
            Variable("alpha_rad", "rad", "angle of attack"),
            Variable("beta_rad", "rad", "sideslip angle"),
            Variable("thrust_N", "N", "propeller thrust"),
        )
        super().__init__(params or FixedWingParams(), inputs, outputs=outputs)

    def structure_key(self) -> str | None:
        """Built from its parameter defaults alone (``BodyVehicleModel.structure_key``)."""
        return super().structure_key()

    # ------------------------------------------------------------------ pieces
    def air_data(self, x: Any, p: Any) -> tuple[Any, Any, Any, Any, Any]:
        """``(v_air_body, Va, alpha, beta, rho)`` at state ``x``."""
        pv = self.params.view(p)
        R = quat_to_dcm(x[6:10])
        wind = ca.vertcat(pv.wind_north_m_s, pv.wind_east_m_s, pv.wind_down_m_s)
        vr = x[3:6] - R.T @ wind
        va = ca.sqrt(ca.sumsqr(vr) + VA_EPS_M_S**2)
        alpha = ca.atan2(vr[2], vr[0])
        beta = ca.asin(vr[1] / va)
        h = x[15]
        rho_ratio = isa(h)[2] / isa(pv.home_height_m)[2]
        rho = pv.rho_kg_m3 * (1.0 + pv.density_altitude_scaling * (rho_ratio - 1.0))
        return vr, va, alpha, beta, rho

    def propeller(self, va: Any, throttle: Any, rho: Any, pv: Any) -> tuple[Any, Any]:
        """Thrust [N] and torque [N m] of the propeller (Beard & McLain 2nd ed., eqs. 4.18-4.22).

        Written with ``J = 2 pi Va / (Omega D)`` expanded so it stays finite when the propeller stops.
        """
        d = pv.D_prop_m
        two_pi = 2.0 * math.pi
        v_in = pv.V_max_V * throttle
        a = rho * d**5 * pv.C_Q0 / two_pi**2
        b = rho * d**4 * pv.C_Q1 * va / two_pi + pv.KQ_N_m_per_A**2 / pv.R_motor_ohm
        c = rho * d**3 * pv.C_Q2 * va**2 - pv.KQ_N_m_per_A * v_in / pv.R_motor_ohm + pv.KQ_N_m_per_A * pv.i0_A
        omega = ca.fmax((-b + ca.sqrt(ca.fmax(b * b - 4 * a * c, 0.0))) / (2 * a), 0.0)
        thrust = rho * (pv.C_T2 * d**2 * va**2 + pv.C_T1 * d**3 * va * omega / two_pi
                        + pv.C_T0 * d**4 * omega**2 / two_pi**2)
        torque = rho * (pv.C_Q2 * d**3 * va**2 + pv.C_Q1 * d**4 * va * omega / two_pi
                        + pv.C_Q0 * d**5 * omega**2 / two_pi**2)
        return thrust, torque

    def forces_moments(self, x: Any, u: Any, p: Any) -> tuple[Any, Any, dict[str, Any]]:
        """Non-gravitational force [N] and moment [N m] in body axes, and intermediate values."""
        pv = self.params.view(p)
        da, de, dr, dt = u[0], u[1], u[2], u[3]
        pr, qr, rr = x[10], x[11], x[12]
        vr, va, alpha, beta, rho = self.air_data(x, p)
        qbar = 0.5 * rho * va**2
        b, c, s = pv.b_m, pv.c_m, pv.S_wing_m2
        m_, a0 = pv.M_blend, pv.alpha0_rad
        e1 = ca.exp(-m_ * (alpha - a0))
        e2 = ca.exp(m_ * (alpha + a0))
        sigma = (1 + e1 + e2) / ((1 + e1) * (1 + e2))
        cl_lin = pv.C_L_0 + pv.C_L_alpha * alpha
        cl = (1 - sigma) * cl_lin + sigma * 2 * ca.sign(alpha) * ca.sin(alpha) ** 2 * ca.cos(alpha)
        cd = pv.C_D_p + cl_lin**2 / (math.pi * pv.e_oswald * b**2 / s)
        qn = c / (2 * va) * qr
        lift = qbar * s * (cl + pv.C_L_q * qn + pv.C_L_delta_e * de)
        drag = qbar * s * (cd + pv.C_D_q * qn + pv.C_D_delta_e * de)
        pn, rn = b / (2 * va) * pr, b / (2 * va) * rr
        side = qbar * s * (pv.C_Y_0 + pv.C_Y_beta * beta + pv.C_Y_p * pn + pv.C_Y_r * rn
                           + pv.C_Y_delta_a * da + pv.C_Y_delta_r * dr)
        f_aero = ca.vertcat(-ca.cos(alpha) * drag + ca.sin(alpha) * lift, side,
                            -ca.sin(alpha) * drag - ca.cos(alpha) * lift)
        roll = qbar * s * b * (pv.C_ell_0 + pv.C_ell_beta * beta + pv.C_ell_p * pn + pv.C_ell_r * rn
                               + pv.C_ell_delta_a * da + pv.C_ell_delta_r * dr)
        pitch = qbar * s * c * (pv.C_m_0 + pv.C_m_alpha * alpha + pv.C_m_q * qn + pv.C_m_delta_e * de)
        yaw = qbar * s * b * (pv.C_n_0 + pv.C_n_beta * beta + pv.C_n_p * pn + pv.C_n_r * rn
                              + pv.C_n_delta_a * da + pv.C_n_delta_r * dr)
        thrust, torque = self.propeller(va, dt, rho, pv)
        f_ground, m_ground, on_ground = contact_forces(
            x[0:3], x[3:6], x[6:10], x[10:13], GEAR_POINTS, pv.mass_kg, pv.ground_wn_rad_s, pv.ground_zeta,
            pv.ground_mu_roll, pv.ground_mu_side,
        )
        r_ac = ca.vertcat(pv.x_ac_m, 0, 0)
        force = f_aero + ca.vertcat(thrust, 0, 0) + f_ground
        moment = ca.vertcat(roll - torque, pitch, yaw) + ca.cross(r_ac, f_aero) + m_ground
        extras = {"va": va, "alpha": alpha, "beta": beta, "u_r": vr[0], "thrust": thrust, "on_ground": on_ground}
        return force, moment, extras

    # ------------------------------------------------------------------ VehicleModel
    def inertia(self, p: Any) -> Any:
        pv = self.params.view(p)
        return inertia_matrix(pv.Jx_kg_m2, pv.Jy_kg_m2, pv.Jz_kg_m2, pv.Jxz_kg_m2)

    def derivatives(self, t: Any, x: Any, u: Any, p: Any) -> Any:
        return self.body_derivatives(x, u, p)

    def outputs_fn(self, x: Any, u: Any, p: Any) -> Any:
        nav, ex = self.nav_outputs(x, u, p)
        return ca.vertcat(*nav, ex["va"], ex["u_r"], ex["alpha"], ex["beta"], ex["thrust"])

    def initial_state(self, p: Any, u: Any) -> Any:
        return vehicle.initial_body_state(self.params.view(p))

    def post_step(self, x: Any, u: Any, p: Any) -> Any:
        return vehicle.normalize_quaternion(x)
