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
from tests.test_fixed_wing_model import book_conditions
from tests.test_fmu_quadrotor import Instance


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
