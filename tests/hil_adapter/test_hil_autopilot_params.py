"""The autopilot parameter files shipped in autopilot/: well-formed, and consistent with the FMUs and the
adapter's default PWM mapping (X frame for the X quadrotor, SERVO outputs as the mapping reads them, an
ArduPlane minimum airspeed the Aerosonde FMU can trim with its surface range)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from fmu_models.common.units import G0_M_S2
from fmu_models.signals.pwm_mapping import PwmMapping, default_mapping

AUTOPILOT = Path(__file__).resolve().parents[2] / "autopilot"
NAME = re.compile(r"^[A-Z][A-Z0-9_]{0,15}$")  # ArduPilot and PX4 parameter names: at most 16 characters


def ardupilot_params(name: str) -> dict[str, float]:
    params: dict[str, float] = {}
    for line in (AUTOPILOT / "ardupilot" / name).read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        key, value = line.split()
        assert NAME.match(key), key
        assert key not in params, f"{key} twice"
        params[key] = float(value)
    return params


def test_copter_is_an_x_frame_spinning_above_the_fmu_idle() -> None:
    from fmu_models.quadrotor.params import QuadrotorParams

    p = ardupilot_params("copter-f450-x.parm")
    assert p["FRAME_CLASS"] == 1 and p["FRAME_TYPE"] == 1  # quad, X
    idle_us = QuadrotorParams().pwm_idle_us
    spin_arm_us = p["MOT_PWM_MIN"] + p["MOT_SPIN_ARM"] * (p["MOT_PWM_MAX"] - p["MOT_PWM_MIN"])
    assert spin_arm_us > idle_us and p["MOT_SPIN_MIN"] > p["MOT_SPIN_ARM"]
    assert (p["MOT_PWM_MIN"], p["MOT_PWM_MAX"]) == (1000, 2000)  # what the default mapping passes through


def test_plane_outputs_match_the_adapter_mapping_and_its_speeds_can_be_trimmed() -> None:
    from fmu_models.common.simulate import Simulator
    from fmu_models.fixed_wing.model import FixedWingModel
    from fmu_models.fixed_wing.trim import trim

    p = ardupilot_params("plane-aerosonde.parm")
    mapping = PwmMapping.from_ardupilot(p)
    default = default_mapping("fixed_wing")
    assert {(c.target, c.source, c.min_us, c.trim_us, c.max_us, c.reversed) for c in mapping.channels} == {
        (c.target, c.source, c.min_us, c.trim_us, c.max_us, c.reversed) for c in default.channels}
    sim = Simulator(FixedWingModel())
    limit = max(c.out_max for c in default.channels if c.target == "elevator_rad")
    slowest = trim(sim.model, sim.params(), p["AIRSPEED_MIN"])
    assert abs(slowest.elevator_rad) < limit  # the autopilot never asks for a speed the surfaces cannot hold
    cruise = trim(sim.model, sim.params(), p["AIRSPEED_CRUISE"])
    assert p["TRIM_THROTTLE"] / 100 == pytest.approx(cruise.throttle, abs=0.02)
    assert p["AIRSPEED_MIN"] < p["AIRSPEED_CRUISE"] < p["AIRSPEED_MAX"]


def test_px4_params_are_param_set_default_lines() -> None:
    lines = [ln for ln in (AUTOPILOT / "px4" / "px4-rc.params").read_text().splitlines()
             if ln.strip() and not ln.startswith("#")]
    assert lines
    for ln in lines:
        cmd, verb, key, value = ln.split()
        assert (cmd, verb) == ("param", "set-default") and NAME.match(key)
        float(value)


def test_landing_mission_takes_off_first_and_lands_last() -> None:
    rows = (AUTOPILOT / "ardupilot" / "aerosonde-circuit.waypoints").read_text().splitlines()
    assert rows[0] == "QGC WPL 110"
    items = [r.split("\t") for r in rows[1:]]
    assert [int(i[0]) for i in items] == list(range(len(items))) and all(len(i) == 12 for i in items)
    commands = [int(i[3]) for i in items]
    assert commands[1] == 22 and commands[-1] == 21  # MAV_CMD_NAV_TAKEOFF ... MAV_CMD_NAV_LAND


def _glide_deg(items: list[list[str]], k: int) -> float:
    """The descent angle [deg] from waypoint ``k`` to ``k + 1`` (north legs: distance from the latitudes)."""
    from fmu_models.common.wgs84 import radii_of_curvature

    (lat_a, h_a), (lat_b, h_b) = ((float(items[j][8]), float(items[j][10])) for j in (k, k + 1))
    r_m = float(radii_of_curvature(math.radians(lat_a))[0])
    return math.degrees(math.atan2(h_a - h_b, math.radians(lat_b - lat_a) * r_m))


def test_shipped_mission_is_generated_and_its_final_follows_the_glide_path(generated: dict[str, object]) -> None:
    """autopilot/ardupilot/aerosonde-circuit.waypoints is what `uavfmu autopilot-params ... --mission` writes; the
    final approach (final turn, short final, landing point) lies on the glide path derived from the model, and
    ArduPlane's landing slope (the waypoint before LAND to the landing point) is that path."""
    plane = generated["arduplane"]
    shipped = (AUTOPILOT / "ardupilot" / "aerosonde-circuit.waypoints").read_text()
    assert shipped == plane.mission, "regenerate with `uavfmu autopilot-params ... --mission`"
    items = [r.split("\t") for r in shipped.splitlines()[1:]]
    assert plane.glide_deg > 2.0  # not the 1.2 deg approach the flare could not finish from
    for k in (len(items) - 3, len(items) - 2):
        assert _glide_deg(items, k) == pytest.approx(plane.glide_deg, abs=0.1)


# ------------------------------------------------------------------------------------------ generated from the model
GENERATED = {"arduplane": ("ardupilot/plane-aerosonde.parm", "fixed_wing"),
             "arducopter": ("ardupilot/copter-f450-x.parm", "quadrotor"),
             "px4": ("px4/px4-rc.params", "quadrotor")}


@pytest.fixture(scope="module")
def generated(built_fmus: dict[str, Path]) -> dict[str, object]:
    """Each autopilot's parameter set computed once from the default FMUs (the ArduPlane design takes seconds)."""
    from hil_adapter.autopilot_params import autopilot_params

    return {name: autopilot_params(built_fmus[model], name) for name, (_, model) in GENERATED.items()}


@pytest.mark.parametrize("autopilot", sorted(GENERATED))
def test_shipped_files_are_generated_from_the_default_fmus(autopilot: str, generated: dict[str, object]) -> None:
    """autopilot/ holds exactly what `uavfmu autopilot-params` computes from the default FMUs (regenerate with
    `uavfmu autopilot-params dist/<model>.fmu --autopilot <name> -o autopilot/<file>`)."""
    path, _ = GENERATED[autopilot]
    shipped = (AUTOPILOT / path).read_text()
    assert shipped == generated[autopilot].text(), f"autopilot/{path} is out of date: regenerate it"


def test_px4_limits_are_mutually_consistent(generated: dict[str, object]) -> None:
    """PX4 v1.13 constrains each auto speed by its manual maximum (a CRITICAL at boot otherwise); takeoff and
    landing speeds within them; the settings that let pxh `commander takeoff` fly without RC or ground station."""
    v = generated["px4"].values
    assert v["MPC_Z_V_AUTO_UP"] <= v["MPC_Z_VEL_MAX_UP"] and v["MPC_TKO_SPEED"] <= v["MPC_Z_VEL_MAX_UP"]
    assert v["MPC_Z_V_AUTO_DN"] <= v["MPC_Z_VEL_MAX_DN"] and v["MPC_LAND_SPEED"] <= v["MPC_Z_VEL_MAX_DN"]
    assert v["MPC_XY_CRUISE"] <= v["MPC_XY_VEL_MAX"] and v["MPC_VEL_MANUAL"] <= v["MPC_XY_VEL_MAX"]
    # v1.13 set_nav_state: "no RC and no datalink" in takeoff/hold/mission unless COM_RCL_EXCEPT bits 1 and 0 are set
    assert v["NAV_DLL_ACT"] == 0 and int(v["COM_RCL_EXCEPT"]) & 0b11 == 0b11 and v["COM_RC_IN_MODE"] == 1
    assert "NAV_RCL_ACT" not in v  # 0 is outside its documented range 1..6; manual modes keep their RC-loss action
    assert v["MPC_THR_MIN"] < v["MPC_THR_HOVER"] < 1.0


def _arducopter_hover_pwm(v: dict[str, float]) -> float:
    """The PWM at which ArduCopter outputs its hover thrust ``MOT_THST_HOVER``: the thrust demand through its
    curve ``(1 - e) a + e a^2`` inverted (AP_MotorsMulticopter, battery scale 1), then the spin range to PWM."""
    e, t = v["MOT_THST_EXPO"], v["MOT_THST_HOVER"]
    a = ((e - 1) + np.sqrt((1 - e) ** 2 + 4 * e * t)) / (2 * e) if e != 0 else t
    return v["MOT_PWM_MIN"] + (v["MOT_SPIN_MIN"] + (v["MOT_SPIN_MAX"] - v["MOT_SPIN_MIN"]) * a) * (
        v["MOT_PWM_MAX"] - v["MOT_PWM_MIN"])


def test_hover_throttles_hover_the_model(built_fmus: dict[str, Path], generated: dict[str, object]) -> None:
    """The hover settings are the model's own: at PX4's hover control, and at the PWM where ArduCopter outputs
    its hover thrust, the model's thrust equals its weight (1 %). ArduCopter uses at most 0.6875: the default
    F450 asks for more, so its file is clamped, says so, and hovers short of the weight; a lighter vehicle that
    needs no clamp is checked as well."""
    from hil_adapter.autopilot_copter import HOVER_LIMITS, SPIN_MAX, arducopter, thrust_curve
    from hil_adapter.autopilot_params import _Params, _simulator, fmu_parameters

    starts = fmu_parameters(built_fmus["quadrotor"])
    sim, p = _simulator("quadrotor", starts)
    weight = sim.model.params.view(p).mass_kg * G0_M_S2
    px4 = generated["px4"].values
    fac, hover = px4["THR_MDL_FAC"], px4["MPC_THR_HOVER"]
    c = (-(1 - fac) + np.sqrt((1 - fac) ** 2 + 4 * fac * hover)) / (2 * fac) if fac > 0 else hover
    assert thrust_curve(sim, p, np.array([1000.0 + 1000.0 * c]))[0] == pytest.approx(weight, rel=0.01)
    v = generated["arducopter"].values
    assert v["MOT_SPIN_MAX"] == SPIN_MAX
    clamped = [w for w in generated["arducopter"].warnings if w.startswith("MOT_THST_HOVER")]
    at_hover = thrust_curve(sim, p, np.array([_arducopter_hover_pwm(v)]))[0]
    if clamped:
        assert v["MOT_THST_HOVER"] == HOVER_LIMITS[1] and at_hover < weight
    else:
        assert at_hover == pytest.approx(weight, rel=0.01)
    light_sim, light_p = _simulator("quadrotor", {**starts, "mass_kg": 0.6 * starts["mass_kg"]})
    out = _Params()
    arducopter(light_sim, light_p, out)
    assert not [w for w in out.warnings if w.startswith("MOT_THST_HOVER")], out.warnings
    light_weight = 0.6 * weight
    light_hover = thrust_curve(light_sim, light_p, np.array([_arducopter_hover_pwm(out.values)]))[0]
    assert light_hover == pytest.approx(light_weight, rel=0.01)


def _px4_shipped() -> dict[str, float]:
    lines = (AUTOPILOT / "px4" / "px4-rc.params").read_text().splitlines()
    return {ln.split()[2]: float(ln.split()[3]) for ln in lines if ln.strip() and not ln.startswith("#")}


def _fmu_thrust_in_the_air(fmu: Path, pwm_us: float) -> tuple[float, float]:
    """(total thrust [N], mass [kg]) of the quadrotor FMU itself with all four motors held at ``pwm_us`` for 1 s,
    50 m up (the motors' first-order lag settled)."""
    from fmu_models.fmi.host import FmuHost

    host = FmuHost(fmu)
    try:
        host.start({"init_pos_down_m": -50.0})
        dt = 0.01
        for k in range(100):
            host.step(k * dt, dt, {f"pwm_{i}_us": pwm_us for i in range(1, 5)})
        return host.get(["thrust_total_N"])["thrust_total_N"], host.start_value("mass_kg")
    finally:
        host.close()


def test_shipped_hover_values_hover_the_fmu_itself(built_fmus: dict[str, Path]) -> None:
    """Independent of the generator: the values in the shipped files, through the autopilots' own thrust models
    to a PWM (PX4: ``thrust = (1 - f) c + f c^2`` with f = THR_MDL_FAC, control c to 1000 + 1000 c us as the
    adapter maps it; ArduCopter: ``_arducopter_hover_pwm``), and the FMU flown at that PWM: PX4's hover makes the
    FMU's weight (mass start value x g) within 1 %; ArduCopter's, clamped at its 0.6875 maximum (the file says
    so), makes less."""
    fmu = built_fmus["quadrotor"]
    v = _px4_shipped()
    f, hover = v["THR_MDL_FAC"], v["MPC_THR_HOVER"]
    c = hover if f == 0 else (-(1 - f) + math.sqrt((1 - f) ** 2 + 4 * f * hover)) / (2 * f)
    thrust, mass = _fmu_thrust_in_the_air(fmu, 1000.0 + 1000.0 * c)
    assert thrust == pytest.approx(mass * G0_M_S2, rel=0.01)
    copter = ardupilot_params("copter-f450-x.parm")
    assert copter["MOT_THST_HOVER"] == 0.6875 and "WARNING: MOT_THST_HOVER" in (
        AUTOPILOT / "ardupilot" / "copter-f450-x.parm").read_text()
    thrust, mass = _fmu_thrust_in_the_air(fmu, _arducopter_hover_pwm(copter))
    assert thrust < mass * G0_M_S2


def _rate_step(fmu: Path, params: dict[str, float], axis: str, step_deg_s: float, gain_scale: float = 1.0,
               servo_tau_s: float = 0.05, dt: float = 0.0025, duration_s: float = 1.2) -> tuple[np.ndarray, np.ndarray]:
    """ArduPlane's rate loop (AP_FW_Controller: out = FF s r + P s^2 e + I s^2 int e, out in degrees of a
    45-degree throw, saturating at 45) closed around the FMU at its cruise trim, through a first-order servo
    and the adapter's PWM mapping. A rate step of ``step_deg_s`` at t = 0.1 s; (time, measured rate [deg/s])."""
    from fmu_models.fixed_wing.trim import trim
    from fmu_models.fmi.host import FmuHost
    from hil_adapter.autopilot_params import _simulator, fmu_parameters

    prefix, rate_out, surface = {"roll": ("RLL", "rate_body_x_rad_s", "aileron_rad"),
                                 "pitch": ("PTCH", "rate_body_y_rad_s", "elevator_rad")}[axis]
    sim, p = _simulator("fixed_wing", fmu_parameters(fmu))
    va = params["AIRSPEED_CRUISE"]
    t0 = trim(sim.model, p, va)
    mapping = default_mapping("fixed_wing")
    channel = next(c for c in mapping.channels if c.target == surface)

    def to_surface(out_deg: float) -> float:  # ArduPilot: +-45 -> SERVO min..max around trim; then our mapping
        out_deg = min(max(out_deg, -FULL), FULL)
        half = (channel.max_us - channel.trim_us) if out_deg >= 0 else (channel.trim_us - channel.min_us)
        return channel.to_input(channel.trim_us + out_deg / FULL * half)

    trims = {"aileron_rad": t0.aileron_rad, "elevator_rad": t0.elevator_rad, "rudder_rad": t0.rudder_rad,
             "throttle": t0.throttle}
    # the integrator holds the trim deflection, as in steady flight before the step
    sign = 1.0 if to_surface(10.0) > to_surface(0.0) else -1.0
    integ = sign * trims[surface] / channel.out_max * FULL
    ff, kp, ki = (gain_scale * params[f"{prefix}_RATE_{k}"] for k in ("FF", "P", "I"))
    imax_deg = 0.666 * DEG
    host = FmuHost(fmu)
    host.start({"init_vel_body_x_m_s": va * math.cos(t0.alpha_rad), "init_vel_body_z_m_s": va * math.sin(t0.alpha_rad),
                "init_pitch_rad": t0.alpha_rad, "init_pos_down_m": -300.0})
    deflection = trims[surface]
    times, rates = [], []
    try:
        for k in range(round(duration_s / dt)):
            t = k * dt
            rate = host.get([rate_out])[rate_out] * DEG
            demand = step_deg_s if t >= 0.1 else 0.0
            err = demand - rate
            integ = min(max(integ + ki * err * dt, -imax_deg), imax_deg)
            command = to_surface(ff * demand + kp * err + integ)
            deflection += (command - deflection) * (1.0 - math.exp(-dt / servo_tau_s))
            host.step(t, dt, {**trims, surface: deflection})
            times.append(t)
            rates.append(rate)
    finally:
        host.close()
    return np.array(times), np.array(rates)


FULL = 45.0
DEG = 180.0 / math.pi


def _rise_and_overshoot(t: np.ndarray, r: np.ndarray, step: float) -> tuple[float, float]:
    after = t >= 0.1
    t, r = t[after], r[after]
    t10 = t[np.argmax(r >= 0.1 * step)]
    t90 = t[np.argmax(r >= 0.9 * step)] if np.any(r >= 0.9 * step) else math.inf
    return t90 - t10, (r.max() - step) / step


@pytest.mark.parametrize(("axis", "step_deg_s"), [("roll", 30.0), ("pitch", 10.0)])
def test_generated_plane_rate_loops_rise_fast_without_overshoot(axis: str, step_deg_s: float,
                                                                built_fmus: dict[str, Path],
                                                                generated: dict[str, object]) -> None:
    """The generated ArduPlane rate gains, closed in ArduPilot's rate-loop structure (FF + PI on the rate error,
    50 ms servo) around the Aerosonde FMU at its cruise trim: 10-90 % rise under 0.3 s, overshoot under 15 %."""
    params = generated["arduplane"].values
    t, r = _rate_step(built_fmus["fixed_wing"], params, axis, step_deg_s)
    rise, overshoot = _rise_and_overshoot(t, r, step_deg_s)
    print(f"{axis} rate step {step_deg_s} deg/s: rise {rise:.3f} s, overshoot {100 * overshoot:.1f} %")
    assert rise < 0.3 and overshoot < 0.15
    # the bound is not loose: a third of the gains misses it
    t, r = _rate_step(built_fmus["fixed_wing"], params, axis, step_deg_s, gain_scale=0.3)
    assert _rise_and_overshoot(t, r, step_deg_s)[0] >= 0.3


#: the steady-state window and tolerance of a rate loop: the mean rate over the last 0.3 s of the 1.2 s response
#: within 5 % of the demand (a loop that settles 7 % short fails)
SETTLE_WINDOW_S, SETTLE_TOL = 0.3, 0.05


def _settled(t: np.ndarray, r: np.ndarray, step: float) -> float:
    """The mean rate over the last ``SETTLE_WINDOW_S`` of the response, as a fraction of the step."""
    return float(np.mean(r[t >= t[-1] - SETTLE_WINDOW_S]) / step)


def test_the_steady_state_check_rejects_a_loop_settling_seven_percent_short() -> None:
    t = np.arange(0.0, 1.2, 0.0025)
    first_order = 1.0 - np.exp(-np.maximum(t - 0.1, 0.0) / 0.08)
    assert abs(_settled(t, 10.0 * first_order, 10.0) - 1.0) <= SETTLE_TOL
    assert abs(_settled(t, 0.93 * 10.0 * first_order, 10.0) - 1.0) > SETTLE_TOL


@pytest.mark.parametrize(("axis", "step_deg_s"), [
    ("roll", 30.0),
    pytest.param("pitch", 10.0, marks=pytest.mark.xfail(strict=True, reason=(
        "the generated pitch-rate loop does not hold a sustained 10 deg/s pitch rate: after its first peak it "
        "drops to about 0.6 of the demand and ends 1.2 s at 0.73 (the elevator needed keeps growing as "
        "the pull-up bleeds speed, and the PI loop lags that ramp); its gains are already above ArduPilot's "
        "documented range. Measured, not yet designed out"))),
])
def test_generated_plane_rate_loops_settle_on_the_demand(axis: str, step_deg_s: float, built_fmus: dict[str, Path],
                                                         generated: dict[str, object]) -> None:
    """The same closed loops as above, held for 1.2 s: the rate settles within 5 % of the demand."""
    t, r = _rate_step(built_fmus["fixed_wing"], generated["arduplane"].values, axis, step_deg_s)
    settled = _settled(t, r, step_deg_s)
    print(f"{axis} rate step {step_deg_s} deg/s: {settled:.3f} of the demand over the last {SETTLE_WINDOW_S} s")
    assert abs(settled - 1.0) <= SETTLE_TOL, f"{axis}: settles at {settled:.3f} of the demand"


def test_wrong_vehicle_and_bad_options_are_clear_errors(built_fmus: dict[str, Path], tmp_path: Path) -> None:
    from hil_adapter.autopilot_params import autopilot_params

    with pytest.raises(ValueError, match="quadrotor model; arduplane flies a fixed_wing"):
        autopilot_params(built_fmus["quadrotor"], "arduplane")
    with pytest.raises(ValueError, match="allowed arduplane, arducopter, px4"):
        autopilot_params(built_fmus["quadrotor"], "inav")
    with pytest.raises(ValueError, match=r"servo_tau_s = 0.0: allowed 0 < tau <= 0.5 s"):
        autopilot_params(built_fmus["fixed_wing"], "arduplane", servo_tau_s=0.0)
    out = autopilot_params(built_fmus["quadrotor"], "px4").write(tmp_path / "p.params")
    assert out.read_text().startswith("#!/bin/sh\n") and "param set-default MPC_THR_HOVER" in out.read_text()


# ------------------------------------------------------------------------------------------ the autopilots' source
# Documented ranges read from the autopilots' own parameter definitions (docs/hil-sitl.md, "Verified against", names the
# stored versions). Every generated parameter is either range-checked here or listed as not yet checked, so a new
# parameter cannot slip in unclassified.
PX4_MPC = "PX4 src/modules/mc_pos_control/mc_pos_control_params.c (v1.13 era)"
PX4_COM = "PX4 src/modules/commander/commander_params.c (v1.13/v1.14)"
PX4_MIX = "PX4 src/lib/mixer_module/params.c"
PX4_NAV = "PX4 src/modules/navigator/mission_params.c"
AP_MOT = "ArduPilot libraries/AP_Motors/AP_MotorsMulticopter.cpp/.h (4.3+)"
AP_COPTER = "ArduPilot ArduCopter/Parameters.cpp (4.5+)"
AP_WPNAV = "ArduPilot libraries/AC_WPNav/AC_WPNav.cpp"
AP_PLANE = "ArduPilot ArduPlane/Parameters.cpp (4.5+)"
AP_TECS = "ArduPilot libraries/AP_TECS/AP_TECS.cpp (4.5+)"
AP_FW = "ArduPilot libraries/APM_Control/AP_{Roll,Pitch}Controller.cpp (4.5+)"
RANGES: dict[str, dict[str, tuple[float, float, str]]] = {
    "px4": {
        "MPC_THR_MIN": (0.05, 1.0, PX4_MPC), "MPC_THR_HOVER": (0.1, 0.8, PX4_MPC), "MPC_USE_HTE": (0, 1, PX4_MPC),
        "MPC_Z_V_AUTO_UP": (0.5, 8.0, PX4_MPC), "MPC_Z_VEL_MAX_UP": (0.5, 8.0, PX4_MPC),
        "MPC_Z_V_AUTO_DN": (0.5, 4.0, PX4_MPC), "MPC_Z_VEL_MAX_DN": (0.5, 4.0, PX4_MPC),
        "MPC_XY_CRUISE": (3.0, 20.0, PX4_MPC), "MPC_VEL_MANUAL": (3.0, 20.0, PX4_MPC),
        "MPC_XY_VEL_MAX": (0.0, 20.0, PX4_MPC), "MPC_TILTMAX_AIR": (20.0, 89.0, PX4_MPC),
        "MPC_LAND_SPEED": (0.6, math.inf, PX4_MPC), "MPC_TKO_SPEED": (1.0, 5.0, PX4_MPC),
        "NAV_DLL_ACT": (0, 6, PX4_COM), "COM_RCL_EXCEPT": (0, 7, PX4_COM), "COM_RC_IN_MODE": (0, 4, PX4_COM),
        "THR_MDL_FAC": (0.0, 1.0, PX4_MIX), "MIS_TAKEOFF_ALT": (0.0, 80.0, PX4_NAV),
    },
    "arducopter": {
        "MOT_THST_EXPO": (-1.0, 1.0, AP_MOT), "MOT_THST_HOVER": (0.125, 0.6875, AP_MOT),
        "MOT_SPIN_ARM": (0.0, 0.2, AP_MOT), "MOT_SPIN_MIN": (0.0, 0.3, AP_MOT), "MOT_SPIN_MAX": (0.9, 1.0, AP_MOT),
        "MOT_PWM_MIN": (0, 2000, AP_MOT), "MOT_PWM_MAX": (0, 2000, AP_MOT), "MOT_HOVER_LEARN": (0, 2, AP_MOT),
        "MOT_BAT_VOLT_MAX": (6.0, 53.0, AP_MOT), "MOT_BAT_VOLT_MIN": (6.0, 42.0, AP_MOT),
        "ANGLE_MAX": (1000, 8000, AP_COPTER), "PILOT_SPEED_UP": (50, 500, AP_COPTER),
        "LAND_SPEED": (30, 200, AP_COPTER), "PILOT_TKOFF_ALT": (0, 1000, AP_COPTER),
        "WPNAV_SPEED_UP": (10, 1000, AP_WPNAV), "WPNAV_SPEED_DN": (10, 500, AP_WPNAV),
    },
    "arduplane": {
        "TKOFF_ROTATE_SPD": (0.0, 30.0, AP_PLANE), "ROLL_LIMIT_DEG": (0.0, 90.0, AP_PLANE),
        "PTCH_LIM_MAX_DEG": (0.0, 90.0, AP_PLANE), "PTCH_LIM_MIN_DEG": (-90.0, 0.0, AP_PLANE),
        "TECS_LAND_TCONST": (1.0, 5.0, AP_TECS), "TECS_LAND_SINK": (0.0, 2.0, AP_TECS),
        "TECS_CLMB_MAX": (0.1, 20.0, AP_TECS), "TECS_SINK_MIN": (0.1, 10.0, AP_TECS),
        "TECS_SINK_MAX": (0.0, 20.0, AP_TECS), "TECS_TIME_CONST": (3.0, 10.0, AP_TECS),
        "TECS_LAND_ARSPD": (-1, 127, AP_TECS), "TECS_LAND_PMAX": (-5, 40, AP_TECS),
        "AIRSPEED_MIN": (5, 100, AP_PLANE), "AIRSPEED_MAX": (5, 100, AP_PLANE),
        "WP_LOITER_RAD": (-32767, 32767, AP_PLANE),
        "RLL2SRV_TCONST": (0.4, 1.0, AP_FW), "PTCH2SRV_TCONST": (0.4, 1.0, AP_FW),
        **{f"{a}_RATE_FF": (0.0, 3.0, AP_FW) for a in ("RLL", "PTCH", "YAW")},
    },
}
#: ranges the autopilot documents but does not enforce (parameter metadata): a generated value may lie outside only
#: with a WARNING line naming it in the file. The D gains are ArduPlane's own default 0 (below the documented 0.001).
ADVISORY = {f"{a}_RATE_{k}": r for a in ("RLL", "PTCH", "YAW") for k, r in (("P", (0.08, 0.35)), ("I", (0.01, 0.6)))}
NOT_YET_CHECKED = {
    "px4": set(),
    "arducopter": {"FRAME_CLASS", "FRAME_TYPE", "PILOT_SPEED_DN", "WPNAV_SPEED"},
    "arduplane": {"AIRSPEED_CRUISE", "TRIM_THROTTLE", "SCALING_SPEED", "TKOFF_THR_MAX",
                  "TKOFF_ALT", "TKOFF_LVL_ALT", "TKOFF_LVL_PITCH", "YAW_RATE_ENABLE", "WP_RADIUS",
                  "NAVL1_PERIOD", "NAVL1_DAMPING", "LAND_PITCH_DEG", "LAND_FLARE_SEC", "LAND_FLARE_ALT",
                  "RLL_RATE_D", "PTCH_RATE_D", "YAW_RATE_D"}
                 | {f"SERVO{n}_{k}" for n in range(1, 5) for k in ("FUNCTION", "MIN", "TRIM", "MAX")},
}


@pytest.mark.parametrize("autopilot", sorted(GENERATED))
def test_generated_values_lie_in_the_autopilots_documented_ranges(autopilot: str, generated: dict[str, object]) -> None:
    values, warnings = generated[autopilot].values, generated[autopilot].warnings
    unclassified = set(values) - set(RANGES[autopilot]) - set(ADVISORY) - NOT_YET_CHECKED[autopilot]
    assert not unclassified, f"{autopilot}: add {sorted(unclassified)} to RANGES (with its source) or NOT_YET_CHECKED"
    for name, (lo, hi, source) in RANGES[autopilot].items():
        if name in values:
            assert lo <= values[name] <= hi, f"{name} = {values[name]} outside {lo}..{hi} ({source})"
    for name, (lo, hi) in ADVISORY.items():
        if name in values and not lo <= values[name] <= hi:
            assert any(w.startswith(f"{name} = ") for w in warnings), f"{name} outside {lo}..{hi} without a warning"


def test_plane_roll_limit_keeps_its_stall_margin_with_the_controllers_overshoot(built_fmus: dict[str, Path],
                                                                                 generated: dict[str, object]) -> None:
    """The roll the controller reaches (the limit plus the rate loops' design overshoot) stays at or under the bank
    that keeps 1.15 x the stall speed at cruise (SITL flew 39.45 deg on a 39 deg limit)."""
    from hil_adapter.autopilot_params import _simulator, fmu_parameters
    from hil_adapter.autopilot_plane import OVERSHOOT_MAX, _Trimmer

    v = generated["arduplane"].values
    vs = _Trimmer(*_simulator("fixed_wing", fmu_parameters(built_fmus["fixed_wing"]))).slowest()
    bank_deg = math.degrees(math.acos(min(1.0, (1.15 * vs) ** 2 / v["AIRSPEED_CRUISE"] ** 2)))
    assert v["ROLL_LIMIT_DEG"] * (1 + OVERSHOOT_MAX) <= bank_deg


def test_plane_speeds_follow_arduplanes_documented_advice(generated: dict[str, object]) -> None:
    """ArduPlane/Parameters.cpp: AIRSPEED_MAX at least 50 % above AIRSPEED_MIN (for TECS height control);
    AP_TECS: TECS_LAND_TCONST smaller than TECS_TIME_CONST."""
    v = generated["arduplane"].values
    assert v["AIRSPEED_MAX"] >= 1.5 * v["AIRSPEED_MIN"]
    assert v["TECS_LAND_TCONST"] < v["TECS_TIME_CONST"]


def test_px4_values_pass_the_position_controllers_boot_checks(generated: dict[str, object]) -> None:
    """MulticopterPositionControl::parameters_update() resets (with a CRITICAL) a cruise or manual speed above
    MPC_XY_VEL_MAX, an auto climb/descent speed above the manual maximum, a hover thrust outside MPC_THR_MIN..MAX
    (MPC_THR_MAX default 1) and MPC_TILTMAX_LND (default 12) above MPC_TILTMAX_AIR."""
    v = generated["px4"].values
    assert v["MPC_XY_CRUISE"] <= v["MPC_XY_VEL_MAX"] and v["MPC_VEL_MANUAL"] <= v["MPC_XY_VEL_MAX"]
    assert v["MPC_Z_V_AUTO_UP"] <= v["MPC_Z_VEL_MAX_UP"] and v["MPC_Z_V_AUTO_DN"] <= v["MPC_Z_VEL_MAX_DN"]
    assert v["MPC_THR_MIN"] <= v["MPC_THR_HOVER"] <= 1.0 and 12.0 <= v["MPC_TILTMAX_AIR"]


def test_a_value_outside_the_autopilots_range_is_clamped_with_a_warning_in_the_file() -> None:
    from hil_adapter.autopilot_params import AutopilotParams, _Params

    out = _Params()
    assert out.clamp("MOT_THST_EXPO", -1.28, -1.0, 1.0, "AP_Motors") == -1.0
    assert out.clamp("MOT_SPIN_MAX", 0.95, 0.9, 1.0, "AP_Motors") == 0.95  # inside: no warning
    assert out.warnings == ["MOT_THST_EXPO: the model gives -1.28, outside -1..1 (AP_Motors): clamped to -1"]
    out.advise("PTCH_RATE_P", 0.3, 0.08, 0.35, "AP_PitchController")  # inside: nothing
    out.advise("PTCH_RATE_P", 1.149, 0.08, 0.35, "AP_PitchController")  # outside a documented-only range: kept, warned
    assert len(out.warnings) == 2 and out.warnings[1].startswith("PTCH_RATE_P = 1.149 lies outside 0.08..0.35")
    text = AutopilotParams("arducopter", "quadrotor", "q.fmu", {"MOT_THST_EXPO": -1.0}, {}, tuple(out.warnings)).text()
    assert "# WARNING: MOT_THST_EXPO: the model gives -1.28" in text


def test_generated_plane_lands_under_1_m_s_near_the_point(built_fmus: dict[str, Path],
                                                          generated: dict[str, object]) -> None:
    """The generated landing settings flown on the Aerosonde FMU in ArduPlane's landing structure (AP_TECS energy
    control on the approach, AP_Landing's flare trigger, the flare's sink-rate demand with the motor stopped and
    its pitch limits, attitude and rate loops: tests/fakes/arduplane.py) from the mission's final turn (its
    height on the glide path) to touchdown: sink under 1 m/s, airspeed above the slowest level trim (no stall),
    within 50 m of the landing point. The settings SITL failed with (approach at AIRSPEED_MIN, a flare pitch floor
    at its trim angle of attack, a 1.2 deg approach) touch down above 1 m/s and below that speed in the same fake."""
    from tests.fakes.arduplane import fly_landing

    plane = generated["arduplane"]
    v = plane.values
    vs = v["TKOFF_ROTATE_SPD"] - 1  # below the slowest trim (19.9 m/s, rounded up to 20)
    items = [r.split("\t") for r in plane.mission.splitlines()[1:]]
    final_height = float(items[-3][10])
    landing = fly_landing(built_fmus["fixed_wing"], v, plane.glide_deg, start_height_m=final_height)
    print(f"landing: flare at {landing.flare_height_m:.2f} m, touchdown sink {landing.touchdown_sink_m_s:.2f} m/s, "
          f"airspeed {landing.touchdown_airspeed_m_s:.1f} m/s, {landing.touchdown_north_m:+.0f} m from the point")
    assert landing.touchdown_sink_m_s < 1.0
    assert landing.touchdown_airspeed_m_s > vs
    assert abs(landing.touchdown_north_m) < 50.0
    old = {**v, "TECS_LAND_ARSPD": v["AIRSPEED_MIN"], "LAND_PITCH_DEG": 4.5, "TECS_LAND_TCONST": 4.0,
           "LAND_FLARE_SEC": 2.2}
    old.pop("TECS_LAND_PMAX")
    failed = fly_landing(built_fmus["fixed_wing"], old, 1.2, start_height_m=15.0)
    assert failed.touchdown_sink_m_s > 1.0 and failed.touchdown_airspeed_m_s < vs + 1  # the check can fail
