"""fixed_wing.fmu through FMPy: validation, published trim held by the FMU, FMU vs Python physics, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from fmu_models.common.rigid_body import euler_from_quat
from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import trim
from tests.fmu_models.fmi.test_fmu_quadrotor import Instance
from tests.fmu_models.test_fixed_wing_model import book_conditions


def test_validator_reports_no_problems(fixed_wing_fmu: Path) -> None:
    assert validate_fmu(str(fixed_wing_fmu)) == []


def test_variables_have_units_and_table1_outputs(fixed_wing_fmu: Path) -> None:
    md = read_model_description(str(fixed_wing_fmu))
    by_name = {v.name: v for v in md.modelVariables}
    for name in ("accel_body_x_m_s2", "accel_body_y_m_s2", "airspeed_body_x_m_s", "altitude_m", "rate_body_x_rad_s",
                 "rate_body_y_rad_s", "rate_body_z_rad_s", "lat_deg", "lon_deg", "height_m", "vel_north_m_s",
                 "vel_east_m_s", "vel_down_m_s", "alpha_rad", "beta_rad", "airspeed_m_s"):
        assert by_name[name].causality == "output" and by_name[name].unit, name
    for name in ("C_ell_p", "C_ell_delta_a", "x_ac_m", "Jxz_kg_m2", "wind_north_m_s"):
        assert by_name[name].causality == "parameter" and by_name[name].variability == "tunable"
    for name in ("C_D_0", "C_D_alpha", "epsilon"):  # reference values of the book the model does not use
        assert name not in by_name


def trim_start_values() -> tuple[dict[str, float], np.ndarray]:
    sim = Simulator(FixedWingModel())
    p = book_conditions(sim)
    t = trim(sim.model, p, 25.0)
    _roll, pitch, _yaw = np.asarray(euler_from_quat(t.x[6:10])).ravel()
    names = sim.model.params.names
    start = {n: float(p[i]) for i, n in enumerate(names) if n in ("home_lat_deg", "home_height_m",
                                                                   "density_altitude_scaling")}
    start.update(init_pos_down_m=-100.0, init_vel_body_x_m_s=float(t.x[3]), init_vel_body_z_m_s=float(t.x[5]),
                 init_pitch_rad=float(pitch), aileron_rad=float(t.u[0]), elevator_rad=float(t.u[1]),
                 rudder_rad=float(t.u[2]), throttle=float(t.u[3]))
    return start, t.u


def test_fmu_holds_published_trim(fixed_wing_fmu: Path) -> None:
    start, _ = trim_start_values()
    res = simulate_fmu(str(fixed_wing_fmu), stop_time=5.0, output_interval=0.01, start_values=start,
                       output=["airspeed_m_s", "altitude_m", "alpha_rad", "roll_rad"])
    assert np.max(np.abs(res["airspeed_m_s"] - 25.0)) < 0.05
    assert np.max(np.abs(res["altitude_m"] - 100.0)) < 0.5
    assert res["alpha_rad"][0] == pytest.approx(0.050011, abs=1e-3)


def test_fmu_matches_python_physics_in_a_manoeuvre(fixed_wing_fmu: Path) -> None:
    start, u = trim_start_values()
    start["aileron_rad"] = float(u[0]) + 0.05
    res = simulate_fmu(str(fixed_wing_fmu), stop_time=3.0, output_interval=0.01, start_values=start,
                       output=["roll_rad", "pitch_rad", "altitude_m", "accel_body_y_m_s2"])
    sim = Simulator(FixedWingModel())
    p = sim.params(**{k: v for k, v in start.items() if k in sim.model.params.index})
    uu = sim.inputs(**{k: v for k, v in start.items() if k in sim.model.inputs.index})
    t, _, Y = sim.run(uu, p, 3.0, 0.001)
    for name in ("roll_rad", "pitch_rad", "altitude_m", "accel_body_y_m_s2"):
        ref = np.interp(res["time"], t, Y[:, sim.model.outputs.index[name]])
        np.testing.assert_allclose(res[name], ref, atol=1e-6, err_msg=name)
    assert res["roll_rad"][-1] > 0.2


def test_out_of_range_throttle_is_an_error(fixed_wing_fmu: Path) -> None:
    with Instance(fixed_wing_fmu) as fmu:
        fmu.set(throttle=1.5)
        with pytest.raises(FMICallException) as err:
            fmu.step(0.01)
        assert err.value.status == 3
        assert "throttle = 1.5 is outside its allowed range [0.0, 1.0]" in fmu.text()


def autopilot_pwm(pitch_ref_rad: float, roll: float, pitch: float, p: float, q: float, r: float) -> dict[int, float]:
    """A small attitude controller written the way ArduPlane and PX4 command: PWM above trim (1500 us) is
    roll right (out 1), pull = nose up (out 2), right rudder = nose right (out 4); full throttle (out 3)."""
    def pwm(x: float) -> float:
        return min(max(1500.0 + 400.0 * x, 1100.0), 1900.0)

    return {1: pwm(-2.0 * roll - 0.3 * p), 2: pwm(3.0 * (pitch_ref_rad - pitch) - 0.5 * q), 3: 2000.0,
            4: pwm(-1.0 * r)}


def test_closed_loop_autopilot_convention_climbs_through_default_mapping(fixed_wing_fmu: Path) -> None:
    from fmu_models.signals.pwm_mapping import default_mapping

    mapping = default_mapping("fixed_wing")
    start, _ = trim_start_values()
    names = ("roll_rad", "pitch_rad", "rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s", "altitude_m")
    with Instance(fixed_wing_fmu, **start) as fmu:
        h0 = fmu.get("altitude_m")[0]
        pitches = []
        for _ in range(800):  # 8 s at 100 Hz
            roll, pitch, p, q, r, _h = fmu.get(*names)
            fmu.set(**mapping.apply(autopilot_pwm(np.radians(12.0), roll, pitch, p, q, r)))
            fmu.step(0.01)
            pitches.append(pitch)
        roll, pitch, *_, h1 = fmu.get(*names)
    assert h1 - h0 > 15.0, f"climbed only {h1 - h0:.1f} m"
    assert abs(np.degrees(np.mean(pitches[-200:])) - 12.0) < 4.0 and abs(roll) < 0.1


def test_right_rudder_and_pull_move_the_nose_as_autopilots_expect(fixed_wing_fmu: Path) -> None:
    from fmu_models.signals.pwm_mapping import default_mapping

    mapping = default_mapping("fixed_wing")
    start, u = trim_start_values()
    trim_pwm = {1: 1500.0, 2: 1500.0, 3: 2000.0, 4: 1500.0}
    for channel, output in ((2, "rate_body_y_rad_s"), (4, "rate_body_z_rad_s")):
        with Instance(fixed_wing_fmu, **start) as fmu:
            inputs = mapping.apply(trim_pwm | {channel: 1700.0})
            inputs.update(throttle=float(u[3]))
            fmu.set(**inputs)
            fmu.step(0.01, 30)
            assert fmu.get(output)[0] > 0.05, output  # nose up (q > 0), nose right (r > 0)


def test_input_descriptions_state_the_sign_convention(fixed_wing_fmu: Path) -> None:
    md = read_model_description(str(fixed_wing_fmu))
    desc = {v.name: v.description for v in md.modelVariables if v.causality == "input"}
    assert "rolls right" in desc["aileron_rad"]
    assert "nose down" in desc["elevator_rad"] and "nose left" in desc["rudder_rad"]
