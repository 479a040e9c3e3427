"""ArduCopter and PX4 parameters from the quadrotor model (see ``hil_adapter.autopilot_params``).

The total thrust at a PWM comes from the model itself: at rest in the air and level, the vertical acceleration
with all four motors at that PWM minus the one with the motors at idle, times the mass (``thrust_curve``): the
thrust map, its band extension, idle and voltage law exactly as the FMU evaluates them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fmu_models.common.units import G0_M_S2
from fmu_models.quadrotor.constants import CELL_EMPTY_V, CELL_FULL_V, CELL_NOMINAL_V

PWM_MIN_US, PWM_MAX_US = 1000.0, 2000.0
SPIN_MAX = 0.95  #: ArduCopter's MOT_SPIN_MAX default
#: ArduCopter constrains MOT_THST_EXPO to [-1, 1] (AP_MotorsMulticopter / Thrust_Linearization)
EXPO_LIMITS = (-1.0, 1.0)
#: ArduCopter constrains the hover thrust it uses and learns to [0.125, 0.6875] (AP_MOTORS_THST_HOVER_MIN/MAX)
HOVER_LIMITS = (0.125, 0.6875)
AP_MOTORS = "ArduPilot libraries/AP_Motors/AP_MotorsMulticopter"
#: PX4 v1.13 ranges (mc_pos_control_params.c; mixer THR_MDL_FAC 0..1)
PX4_TILT_DEG = (20.0, 89.0)
PX4_CLIMB_M_S = (1.0, 8.0)  #: MPC_Z_VEL_MAX_UP 0.5..8, floored at MPC_TKO_SPEED's minimum 1 m/s
PX4_LAND_SPEED_MIN_M_S = 0.6


def thrust_curve(sim: Any, p: np.ndarray, pwm_us: np.ndarray) -> np.ndarray:
    """Total thrust [N] of the four motors at each (common) PWM, from the model's vertical acceleration."""
    pv = sim.model.params.view(p)
    p_air = p.copy()
    p_air[sim.model.params.index["init_pos_down_m"]] = -50.0  # in the air: no ground contact
    w_dot = sim.model.states.index["vel_body_z_m_s"]

    def accel(pwm: float) -> float:
        u = sim.inputs(pwm_1_us=pwm, pwm_2_us=pwm, pwm_3_us=pwm, pwm_4_us=pwm)
        x, _ = sim.initial(u, p_air)
        return float(np.asarray(sim.f(x, sim.full_inputs(u), p_air)).ravel()[w_dot])

    g_local = accel(pv.pwm_idle_us)  # no thrust: gravity alone (WGS-84 normal gravity at home)
    return np.array([pv.mass_kg * (g_local - accel(float(x))) for x in pwm_us])


def _expo(a: np.ndarray, thrust: np.ndarray) -> float:
    """Least-squares ``e`` of ``t = (1 - e) a + e a^2`` (ArduPilot's and PX4's thrust model) on normalised
    thrust ``t = thrust / thrust[-1]`` over actuator ``a`` in [0, 1]."""
    t = thrust / thrust[-1]
    basis = a * a - a
    return float(np.dot(basis, t - a) / np.dot(basis, basis))


def _hover_pwm(sim: Any, p: np.ndarray, weight_n: float) -> float:
    lo, hi = sim.model.params.view(p).pwm_idle_us, PWM_MAX_US
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if thrust_curve(sim, p, np.array([mid]))[0] < weight_n else (lo, mid)
    return 0.5 * (lo + hi)


def _weight(sim: Any, p: np.ndarray) -> float:
    pv = sim.model.params.view(p)
    return pv.mass_kg * G0_M_S2


def arducopter(sim: Any, p: np.ndarray, out: Any) -> None:
    """ArduCopter: X frame, spin range above the model's idle, hover throttle, expo and battery range."""
    pv = sim.model.params.view(p)
    out("FRAME_CLASS", 1, "quad")
    out("FRAME_TYPE", 1, "X (motor order as the FMU: fmu_models/quadrotor/readme.md)")
    out("MOT_PWM_MIN", PWM_MIN_US, "the adapter passes motor PWM straight into pwm_1_us..pwm_4_us")
    out("MOT_PWM_MAX", PWM_MAX_US)
    idle = (pv.pwm_idle_us - PWM_MIN_US) / (PWM_MAX_US - PWM_MIN_US)
    arm = out("MOT_SPIN_ARM", round(idle + 0.02, 3), f"the model's idle {pv.pwm_idle_us:.0f} us + 2 % (ArduPilot's"
                                                     " rule: dead zone + 2 %)")
    spin_min = out("MOT_SPIN_MIN", round(arm + 0.03, 3), "MOT_SPIN_ARM + 0.03 (ArduPilot's rule)")
    out("MOT_SPIN_MAX", SPIN_MAX)
    a = np.linspace(0.0, 1.0, 21)
    pwm = PWM_MIN_US + (spin_min + (SPIN_MAX - spin_min) * a) * (PWM_MAX_US - PWM_MIN_US)
    thrust = thrust_curve(sim, p, pwm)
    expo = out.clamp("MOT_THST_EXPO", _expo(a, thrust), *EXPO_LIMITS, f"{AP_MOTORS}.cpp constrains it")
    rms = float(np.sqrt(np.mean((thrust / thrust[-1] - ((1 - expo) * a + expo * a * a)) ** 2)))
    out("MOT_THST_EXPO", round(expo, 3), "least squares of thrust/thrust(spin max) = (1-e) a + e a^2 over the "
                                         f"spin range (model thrust map; rms misfit {rms:.3f} after any clamp)")
    pwm_hover = _hover_pwm(sim, p, _weight(sim, p))
    a_h = ((pwm_hover - PWM_MIN_US) / (PWM_MAX_US - PWM_MIN_US) - spin_min) / (SPIN_MAX - spin_min)
    hover = out.clamp("MOT_THST_HOVER", (1 - expo) * a_h + expo * a_h * a_h, *HOVER_LIMITS,
                      f"{AP_MOTORS}.h AP_MOTORS_THST_HOVER_MIN/MAX, applied by get_throttle_hover() and the learner; "
                      "the altitude controller's integrator supplies the rest")
    out("MOT_THST_HOVER", round(hover, 4),
        f"the model hovers at {pwm_hover:.0f} us (actuator {a_h:.3f} of the spin range): its thrust on the curve "
        "above, so that ArduCopter's thrust-to-actuator mapping puts hover there")
    out("MOT_HOVER_LEARN", 2, "learned and saved in flight from there on")
    cells = max(1, round(pv.battery_nominal_V / CELL_NOMINAL_V))
    out("MOT_BAT_VOLT_MAX", round(cells * CELL_FULL_V, 2), f"{cells} cells (battery_nominal_V "
                                                           f"{pv.battery_nominal_V} V) x 4.2 V")
    out("MOT_BAT_VOLT_MIN", round(cells * CELL_EMPTY_V, 2), f"{cells} cells x 3.3 V")
    tw = thrust[-1] / _weight(sim, p)
    tilt = _tilt_deg(tw)
    out("ANGLE_MAX", 100 * tilt, f"thrust/weight {tw:.2f}: keep 10 % vertical thrust reserve at full tilt [cdeg]")
    climb = _climb_m_s(tw, _weight(sim, p), pv.kd_z_N_s_m)
    out("PILOT_SPEED_UP", round(100 * climb), "half the excess thrust against the vertical drag [cm/s]")
    out("WPNAV_SPEED_UP", round(100 * climb))
    out("PILOT_SPEED_DN", round(100 * min(climb, 1.5)), "[cm/s]")
    out("WPNAV_SPEED_DN", round(100 * min(climb, 1.5)))
    out("WPNAV_SPEED", 300, "[cm/s]")
    out("LAND_SPEED", 50, "[cm/s]")
    out("PILOT_TKOFF_ALT", 250, "[cm]")


def _tilt_deg(thrust_to_weight: float) -> float:
    """The tilt at which full thrust still holds 1.1 x the weight vertically (10..35 degrees)."""
    return round(min(35.0, max(10.0, math.degrees(math.acos(min(1.0, 1.1 / thrust_to_weight))))))


def _climb_m_s(thrust_to_weight: float, weight_n: float, kd_z: float) -> float:
    """Climb speed using half the excess thrust against the linear drag (0.5..3 m/s)."""
    excess = max(thrust_to_weight - 1.0, 0.0) * weight_n
    return round(min(3.0, max(0.5, 0.5 * excess / max(kd_z, 1e-3))), 1)


def px4(sim: Any, p: np.ndarray, out: Any) -> None:
    """PX4 v1.13 multicopter: hover thrust and thrust model, consistent speed limits, no-GCS/no-RC flight."""
    pv = sim.model.params.view(p)
    c = np.linspace(0.0, 1.0, 21)  # PX4 control 0..1 -> 1000..2000 us in the adapter
    thrust = thrust_curve(sim, p, PWM_MIN_US + c * (PWM_MAX_US - PWM_MIN_US))
    weight = _weight(sim, p)
    fac = out("THR_MDL_FAC", round(out.clamp("THR_MDL_FAC", _expo(c, thrust), 0.0, 1.0, "PX4 THR_MDL_FAC range"), 3),
              "least squares of thrust/thrust(1) = (1-f) c + f c^2 over control 0..1 (model thrust map)")
    c_hover = (_hover_pwm(sim, p, weight) - PWM_MIN_US) / (PWM_MAX_US - PWM_MIN_US)
    out("MPC_THR_HOVER", round(out.clamp("MPC_THR_HOVER", (1 - fac) * c_hover + fac * c_hover ** 2, 0.1, 0.8,
                                         "PX4 range"), 3),
        f"hover at control {c_hover:.3f} ({PWM_MIN_US + 1000 * c_hover:.0f} us), through THR_MDL_FAC")
    out("MPC_USE_HTE", 1, "hover thrust estimator on")
    c_idle = (pv.pwm_idle_us - PWM_MIN_US) / (PWM_MAX_US - PWM_MIN_US)
    out("MPC_THR_MIN", round((1 - fac) * (c_idle + 0.05) + fac * (c_idle + 0.05) ** 2, 3),
        f"5 % above the model's idle control {c_idle:.2f}")
    tw = thrust[-1] / weight
    out("MPC_TILTMAX_AIR", out.clamp("MPC_TILTMAX_AIR", _tilt_deg(tw), *PX4_TILT_DEG, "PX4 range"),
        f"thrust/weight {tw:.2f}: 10 % vertical reserve at full tilt [deg]")
    climb = out.clamp("MPC_Z_VEL_MAX_UP", _climb_m_s(tw, weight, pv.kd_z_N_s_m), *PX4_CLIMB_M_S,
                      "PX4 range, floored at MPC_TKO_SPEED's minimum")
    up = out("MPC_Z_VEL_MAX_UP", climb, "half the excess thrust against the vertical drag [m/s]")
    out("MPC_Z_V_AUTO_UP", up, "= MPC_Z_VEL_MAX_UP (PX4 resets a larger one with a CRITICAL at boot)")
    out("MPC_TKO_SPEED", 1.0, "PX4's minimum, <= MPC_Z_VEL_MAX_UP [m/s]")
    dn = out("MPC_Z_VEL_MAX_DN", 1.0, "[m/s]")
    out("MPC_Z_V_AUTO_DN", dn, "= MPC_Z_VEL_MAX_DN (PX4 resets a larger one with a CRITICAL at boot)")
    out("MPC_LAND_SPEED", PX4_LAND_SPEED_MIN_M_S, "PX4's minimum: the softest touchdown it allows [m/s]")
    out("MPC_XY_VEL_MAX", 5.0, "[m/s]")
    out("MPC_XY_CRUISE", 3.0, "<= MPC_XY_VEL_MAX")
    out("MPC_VEL_MANUAL", 3.0, "<= MPC_XY_VEL_MAX")
    out("MIS_TAKEOFF_ALT", 2.5, "commander takeoff climbs to this [m]")
    _px4_no_gcs(out)


def _px4_no_gcs(out: Any) -> None:
    """PX4 v1.13 (state_machine_helper.cpp set_nav_state): with neither RC nor a ground station, takeoff, hold and
    mission fail safe with "no RC and no datalink" unless COM_RCL_EXCEPT exempts them (bit 0 mission, bit 1 hold,
    which covers takeoff); NAV_DLL_ACT 0 keeps the data-link-loss failsafe ("no datalink") off."""
    out("NAV_DLL_ACT", 0, "no ground station: no data-link-loss failsafe (v1.13 default, stated)")
    out("COM_RCL_EXCEPT", 3, "RC loss ignored in mission (bit 0) and hold/takeoff (bit 1): no 'no RC and no "
                             "datalink' failsafe; manual modes keep the RC-loss action NAV_RCL_ACT")
    out("COM_RC_IN_MODE", 1, "no RC checks at arming (PX4's own SITL rcS default)")
