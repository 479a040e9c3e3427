"""Quadrotor physics (paper 000): published map, thrust extension, hover, moments, ground, frames."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from fmu_models.common import wgs84
from fmu_models.common.errors import ParameterError
from fmu_models.common.simulate import Simulator
from fmu_models.quadrotor.anfis import AnfisMap, published_map
from fmu_models.quadrotor.model import QuadrotorModel
from fmu_models.quadrotor.params import QuadrotorParams
from fmu_models.quadrotor.thrust import out_of_band, thrust_sum

# Paper 000, Tables 2 and 3, typed in again here so the test checks the code against the paper.
TABLE2_MEAN = np.array([5.9244, 6.0103, 5.8000, 5.9619, 6.0452, 6.2173]) * 1e3
TABLE2_STD = np.array([0.0402, 0.1000, 0.1000, 0.0428, 0.0385, 0.0785]) * 1e3
TABLE3 = np.array([10.0, 10.5, 10.6, 11.4, 11.6, 11.9])


def paper_map(x: np.ndarray) -> np.ndarray:
    w = np.exp(-((x[:, None] - TABLE2_MEAN) ** 2) / TABLE2_STD**2)
    return (w * TABLE3).sum(1) / w.sum(1)


@pytest.fixture(scope="module")
def sim() -> Simulator:
    return Simulator(QuadrotorModel())


def hover_pwm_sum(g: float, mass: float = 1.14) -> float:
    """Summed PWM where the published map gives m g, on its rising branch."""
    return brentq(lambda x: paper_map(np.array([x]))[0] - mass * g, 6000.0, 6217.3, xtol=1e-12)


def test_published_map_reproduces_tables_2_3() -> None:
    x = np.linspace(5700, 6400, 701)
    np.testing.assert_allclose(published_map().evaluate([x]), paper_map(x), rtol=0, atol=1e-12)


def test_published_map_folds_back_outside_its_band() -> None:
    amap = published_map()
    assert amap.evaluate([np.array([4000.0])])[0] > amap.evaluate([np.array([5900.0])])[0]


def test_map_json_round_trip_is_exact(tmp_path) -> None:
    amap = published_map()
    amap.save(tmp_path / "m.json")
    assert AnfisMap.load(tmp_path / "m.json") == amap


def test_map_load_reports_every_problem() -> None:
    bad = published_map().to_dict()
    bad["mf_sigma"][0][2] = -1.0
    bad["order"] = 3
    bad["input_range"] = [[6000.0, 5000.0]]
    with pytest.raises(ParameterError) as err:
        AnfisMap.from_dict(bad, source="bad.json")
    text = str(err.value)
    assert "bad.json" in text and "mf_sigma[0][2] = -1.0" in text and "order = 3" in text
    assert "input_range[0]" in text


class TestThrustExtension:
    amap = published_map()
    lo, hi = amap.input_range[0]
    idle = 4 * 1100.0

    def t(self, x: np.ndarray) -> np.ndarray:
        return thrust_sum(self.amap, np.asarray(x, float), self.idle, self.lo, self.hi)

    def test_inside_band_reproduces_map_exactly(self) -> None:
        x = np.linspace(self.lo, self.hi, 500)
        np.testing.assert_array_equal(self.t(x), self.amap.evaluate([x]))

    def test_zero_at_and_below_idle(self) -> None:
        assert np.all(self.t(np.array([0.0, 1000.0, 4000.0, self.idle])) == 0.0)

    def test_grows_from_idle_to_band_and_is_continuous(self) -> None:
        x = np.linspace(self.idle, self.lo, 400)
        t = self.t(x)
        assert np.all(np.diff(t) > 0)
        assert t[-1] == pytest.approx(self.amap.evaluate([np.array([self.lo])])[0], abs=1e-9)

    def test_grows_above_band_from_edge_value_and_slope(self) -> None:
        x = np.linspace(self.hi, self.hi + 2000, 400)
        t = self.t(x)
        assert np.all(np.diff(t) > 0)
        edge = self.amap.evaluate([np.array([self.hi])])[0]
        assert t[0] == pytest.approx(edge, abs=1e-12)
        h = 1e-3
        slope_edge = (edge - self.amap.evaluate([np.array([self.hi - h])])[0]) / h
        assert slope_edge > 0  # the published map still rises at its top MF centre
        assert (t[-1] - t[0]) / 2000.0 == pytest.approx(slope_edge, rel=1e-6)

    def test_folding_region_is_never_used(self) -> None:
        # per-motor 1000 us -> 4000 us summed: below idle, so zero, not the map's 10.6 N
        assert self.t(np.array([4000.0]))[0] == 0.0
        assert self.t(np.array([4000.0]))[0] < self.t(np.array([5900.0]))[0]

    def test_out_of_range_flag(self) -> None:
        flags = out_of_band(np.array([self.lo - 1, self.lo, 6000.0, self.hi, self.hi + 1]), self.lo, self.hi)
        np.testing.assert_array_equal(flags, [1, 0, 0, 0, 1])


def test_wgs84_normal_gravity_published_values() -> None:
    # NIMA TR8350.2 Table 3.4: gamma_e, gamma_p
    assert float(wgs84.normal_gravity(0.0, 0.0)) == pytest.approx(9.7803253359, abs=1e-10)
    assert float(wgs84.normal_gravity(math.pi / 2, 0.0)) == pytest.approx(9.8321849378, abs=1e-9)
    # free-air gradient ~ -3.086e-6 s^-2 at mid latitude
    grad = float(wgs84.normal_gravity(math.radians(45), 1000.0) - wgs84.normal_gravity(math.radians(45), 0.0))
    assert grad / 1000.0 == pytest.approx(-3.086e-6, rel=2e-3)


def hover_state(sim: Simulator, p: np.ndarray, height_m: float = 10.0) -> tuple[np.ndarray, np.ndarray, float]:
    p = p.copy()
    p[sim.model.params.index["init_pos_down_m"]] = -height_m
    _x, y = sim.initial(sim.inputs(), p)
    g = sim.output(y, "gravity_m_s2")
    pwm = hover_pwm_sum(g) / 4
    u = sim.full_inputs(np.full(4, pwm))  # battery voltage at its nominal start value
    return sim.initial(u, p)[0], u, g


def test_hover_equilibrium_all_derivatives_zero(sim: Simulator) -> None:
    p = sim.params()
    x, u, _ = hover_state(sim, p)
    xdot = np.asarray(sim.f(x, u, p)).ravel()
    np.testing.assert_allclose(xdot[3:13], 0.0, atol=1e-10)


def test_hover_holds_height_for_10_s(sim: Simulator) -> None:
    p = sim.params()
    x0, u, _ = hover_state(sim, p)
    _t, X, _Y = sim.run(u, p, 10.0, 0.01, x0=x0)
    assert np.max(np.abs(X[:, 2] - x0[2])) < 0.01


def test_equal_pwm_gives_no_roll_pitch_moment(sim: Simulator) -> None:
    p = sim.params()
    x, _ = sim.initial(sim.inputs(), p)
    for pwm in (1200.0, 1480.0, 1530.0, 1700.0):
        _, m, _ = sim.model.forces_moments(x, np.full(4, pwm), p)
        m = np.asarray(m).ravel()
        assert abs(m[0]) < 1e-12 and abs(m[1]) < 1e-12


def test_moment_signs_follow_quad_x_layout(sim: Simulator) -> None:
    p = sim.params(init_pos_down_m=-5.0)
    x, _ = sim.initial(sim.inputs(), p)
    base = np.full(4, 1530.0)

    def moment(d: list[float]) -> np.ndarray:
        return np.asarray(sim.model.forces_moments(x, base + np.array(d), p)[1]).ravel()

    assert moment([20, 0, 0, 20])[0] < 0  # right motors (1 front-right, 4 rear-right) up: roll left
    assert moment([20, 0, 20, 0])[1] > 0  # front motors (1, 3) up: nose up
    assert moment([20, 20, 0, 0])[2] > 0  # CCW motors (1, 2) up: reaction yaws the body right


def test_gyroscopic_moment_is_minus_omega_cross_rotor_momentum(sim: Simulator) -> None:
    pr = QuadrotorParams()
    p = sim.params(init_pos_down_m=-5.0, init_rate_body_x_rad_s=2.0, b_drag_N_m_s2=0.0, kd_x_N_s_m=0.0)
    x, _ = sim.initial(sim.inputs(), p)
    u = np.array([1600.0, 1600.0, 1500.0, 1500.0])  # CCW pair faster: net rotor momentum along -z
    _, m, ex = sim.model.forces_moments(x, u, p)
    omega = [float(w) for w in ex["omega"]]
    h = pr.J_rotor_kg_m2 * (-omega[0] - omega[1] + omega[2] + omega[3])  # along +z body
    x_still = x.copy()
    x_still[10] = 0.0
    m_gyro = np.asarray(m).ravel() - np.asarray(sim.model.forces_moments(x_still, u, p)[1]).ravel()
    # -omega x (0, 0, h) with omega = (P, 0, 0) is (0, P h, 0)
    assert abs(h) > 1e-4
    np.testing.assert_allclose(m_gyro, [0.0, 2.0 * h, 0.0], atol=1e-12)


def test_free_fall_accelerometer_reads_zero(sim: Simulator) -> None:
    p = sim.params(init_pos_down_m=-50.0, kd_x_N_s_m=0.0, kd_y_N_s_m=0.0, kd_z_N_s_m=0.0,
                   init_roll_rad=0.3, init_pitch_rad=-0.2)
    u = sim.inputs(pwm_1_us=0, pwm_2_us=0, pwm_3_us=0, pwm_4_us=0)
    _x, y = sim.initial(u, p)
    _t, X, Y = sim.run(u, p, 1.0, 0.01)
    i = [sim.model.outputs.index[f"accel_body_{a}_m_s2"] for a in "xyz"]
    assert np.max(np.abs(Y[:, i])) == 0.0
    g = sim.output(y, "gravity_m_s2")
    assert X[-1, 2] - X[0, 2] == pytest.approx(0.5 * g * 1.0**2, rel=1e-6)


def test_at_rest_on_ground_stays_and_reads_minus_g(sim: Simulator) -> None:
    p = sim.params()
    u = np.full(4, 1000.0)
    _t, X, Y = sim.run(u, p, 10.0, 0.005)
    assert np.max(np.abs(X[:, 2])) < 2e-3  # sinks at most g / wn^2 ~ 1 mm
    assert np.max(np.abs(X[:, 0:2])) < 1e-6
    g = Y[-1, sim.model.outputs.index["gravity_m_s2"]]
    assert Y[-1, sim.model.outputs.index["accel_body_z_m_s2"]] == pytest.approx(-g, abs=1e-3)
    assert Y[-1, sim.model.outputs.index["on_ground"]] == 1.0


def test_takes_off_from_ground(sim: Simulator) -> None:
    p = sim.params()
    _t, X, Y = sim.run(np.full(4, 1700.0), p, 2.0, 0.005)
    assert X[-1, 2] < -1.0 and Y[-1, sim.model.outputs.index["on_ground"]] == 0.0


def test_geodetic_position_follows_ned_velocity(sim: Simulator) -> None:
    p = sim.params(init_pos_down_m=-100.0, init_vel_body_x_m_s=10.0, kd_x_N_s_m=0.0, kd_z_N_s_m=0.0)
    x0, u, _ = hover_state(sim, p, 100.0)
    x0[3] = 10.0
    _t, X, Y = sim.run(u, p, 20.0, 0.01, x0=x0)
    lat0 = math.radians(47.397742)
    r_m, _ = wgs84.radii_of_curvature(lat0)
    dlat = X[-1, 13] - X[0, 13]
    assert dlat == pytest.approx((X[-1, 0] - X[0, 0]) / (float(r_m) + 488.0 + 100.0), rel=1e-6)
    assert Y[-1, sim.model.outputs.index["altitude_m"]] == pytest.approx(-X[-1, 2])


def test_quaternion_stays_unit_while_tumbling(sim: Simulator) -> None:
    p = sim.params(init_pos_down_m=-1000.0, init_rate_body_x_rad_s=3.0, init_rate_body_y_rad_s=-2.0,
                   init_rate_body_z_rad_s=1.0)
    _t, X, _Y = sim.run(np.full(4, 1530.0), p, 5.0, 0.01)
    np.testing.assert_allclose(np.linalg.norm(X[:, 6:10], axis=1), 1.0, atol=1e-12)


def test_motor_lag_is_first_order(sim: Simulator) -> None:
    p = sim.params(init_pos_down_m=-100.0, tau_motor_s=0.05)
    u0 = np.full(4, 1500.0)
    x0, _ = sim.initial(u0, p)
    _t, X, _Y = sim.run(np.full(4, 1600.0), p, 0.05, 0.001, x0=x0)
    t_cmd = float(sim.model.commanded_thrust(np.full(4, 1600.0), p)[0])
    t_start = x0[16]
    frac = (X[-1, 16] - t_start) / (t_cmd - t_start)
    assert frac == pytest.approx(1 - math.exp(-1), abs=1e-4)


def test_params_load_reports_all_problems(tmp_path) -> None:
    f = tmp_path / "p.json"
    f.write_text('{"quadrotor": {"mass_kg": -1, "arm_lenght_m": 0.2, "frame": "hexa"}}')
    with pytest.raises(ParameterError) as err:
        QuadrotorParams.load(f)
    text = str(err.value)
    assert str(f) in text and "mass_kg = -1.0" in text and "arm_lenght_m is not a parameter" in text
    assert "frame = 'hexa'" in text


def test_initial_motor_lag_states_from_init_thrust(sim: Simulator) -> None:
    """``init_thrust_<i>_N`` >= 0 starts motor i's lag there (a restart in mid-manoeuvre); negative (the default)
    at the thrust the first PWM commands."""
    u0 = np.full(4, 1600.0)
    p = sim.params(init_pos_down_m=-100.0, tau_motor_s=0.05, init_thrust_2_N=1.25, init_thrust_4_N=0.0)
    x0, _ = sim.initial(u0, p)
    cmd = [float(v) for v in sim.model.commanded_thrust(u0, p)]
    i = sim.model.states.index["thrust_state_1_N"]
    np.testing.assert_allclose(x0[i:i + 4], [cmd[0], 1.25, cmd[2], 0.0], rtol=1e-12)
    assert cmd[1] > 2.0  # the commanded thrust is far from the given one: the parameter decided
