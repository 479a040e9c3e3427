"""Fixed-wing physics (paper 001, Aerosonde of Beard & McLain): published trim, stability, ground, frames."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from fmu_models.common import wgs84
from fmu_models.common.errors import ParameterError
from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.fixed_wing.trim import trim

# Published with the uavbook (mavsim_python, Beard & McLain 2nd-edition supplement), Va = 25 m/s, gamma = 0:
# trim_state u = 24.968743, w = 1.249755 m/s; trim_input elevator = -0.124778, aileron = 0.001836,
# rudder = -0.000303, throttle = 0.676752.
BOOK_ALPHA = float(np.arctan2(1.249755, 24.968743))
BOOK_ELEVATOR, BOOK_THROTTLE, BOOK_AILERON, BOOK_RUDDER = -0.124778, 0.676752, 0.001836, -0.000303


@pytest.fixture(scope="module")
def sim() -> Simulator:
    return Simulator(FixedWingModel())


def book_conditions(sim: Simulator) -> np.ndarray:
    """The book's world: g = 9.81 m/s^2 (home at the latitude where WGS-84 gives that at 100 m), constant rho."""
    lat = brentq(lambda deg: float(wgs84.normal_gravity(np.radians(deg), 100.0)) - 9.81, 0.0, 89.0)
    return sim.params(home_lat_deg=lat, home_height_m=0.0, density_altitude_scaling=0.0)


def test_wings_level_trim_matches_published_uavbook_trim(sim: Simulator) -> None:
    t = trim(sim.model, book_conditions(sim), 25.0)
    assert t.alpha_rad == pytest.approx(BOOK_ALPHA, abs=1e-3)
    assert t.elevator_rad == pytest.approx(BOOK_ELEVATOR, abs=1e-3)
    assert t.throttle == pytest.approx(BOOK_THROTTLE, abs=1e-3)
    assert t.aileron_rad == pytest.approx(BOOK_AILERON, abs=1e-4)
    assert t.rudder_rad == pytest.approx(BOOK_RUDDER, abs=1e-4)


def test_trim_holds_in_simulation(sim: Simulator) -> None:
    p = book_conditions(sim)
    t = trim(sim.model, p, 25.0)
    _, _X, Y = sim.run(t.u, p, 5.0, 0.01, x0=t.x)
    out = sim.model.outputs.index
    assert Y[-1, out["airspeed_m_s"]] == pytest.approx(25.0, abs=0.05)
    assert abs(Y[-1, out["altitude_m"]] - 100.0) < 0.5
    assert abs(Y[-1, out["roll_rad"]]) < 0.01


def test_linearisation_has_textbook_modes(sim: Simulator) -> None:
    p = book_conditions(sim)
    t = trim(sim.model, p, 25.0)
    import casadi as ca

    x = ca.SX.sym("x", 16)
    A = ca.Function("A", [x], [ca.jacobian(sim.f(x, t.u, p), x)])(t.x).full()
    # longitudinal: u, w, q, theta via quaternion - take eigenvalues of the body-state block
    eig = np.linalg.eigvals(A[3:13, 3:13])
    fast = eig[np.abs(eig.imag) > 1.0]
    assert len(fast) >= 2 and np.all(fast.real < 0)  # short period and dutch roll: damped oscillations
    roll = eig[(np.abs(eig.imag) < 1e-6) & (eig.real < -5)]
    assert len(roll) >= 1  # roll subsidence: a fast real stable pole


def test_at_rest_on_ground_stays_and_reads_minus_g(sim: Simulator) -> None:
    p = sim.params()
    _, X, Y = sim.run(sim.inputs(), p, 10.0, 0.005)
    out = sim.model.outputs.index
    assert np.max(np.abs(X[:, 2])) < 2e-3
    assert np.max(np.abs(X[:, 0:2])) < 1e-3
    assert Y[-1, out["accel_body_z_m_s2"]] == pytest.approx(-Y[-1, out["gravity_m_s2"]], abs=1e-3)


def test_takes_off_with_full_throttle(sim: Simulator) -> None:
    p = sim.params()
    _, _X, Y = sim.run(sim.inputs(throttle=1.0, elevator_rad=-0.25), p, 25.0, 0.01)
    out = sim.model.outputs.index
    assert Y[-1, out["altitude_m"]] > 5.0 and Y[-1, out["on_ground"]] == 0.0


def test_quaternion_stays_unit(sim: Simulator) -> None:
    p = sim.params(init_pos_down_m=-500.0, init_vel_body_x_m_s=25.0)
    _, X, _ = sim.run(sim.inputs(aileron_rad=0.3, throttle=0.7), p, 5.0, 0.01)
    np.testing.assert_allclose(np.linalg.norm(X[:, 6:10], axis=1), 1.0, atol=1e-12)


def test_aileron_rolls_right_and_wind_changes_airspeed(sim: Simulator) -> None:
    p = sim.params(init_pos_down_m=-500.0, init_vel_body_x_m_s=25.0)
    _, _, Y = sim.run(sim.inputs(aileron_rad=0.1, throttle=0.7), p, 0.5, 0.01)
    assert Y[-1, sim.model.outputs.index["roll_rad"]] > 0.05
    x0, _ = sim.initial(sim.inputs(), p)
    head = sim.params(init_pos_down_m=-500.0, init_vel_body_x_m_s=25.0, wind_north_m_s=-5.0)
    y = np.asarray(sim.h(x0, sim.inputs(), head)).ravel()
    assert y[sim.model.outputs.index["airspeed_m_s"]] == pytest.approx(30.0, abs=1e-6)


def test_params_load_reports_all_problems(tmp_path) -> None:
    f = tmp_path / "fw.json"
    f.write_text('{"fixed_wing": {"mass_kg": 0, "C_ell_pp": 1, "epsilon": 0.1, "propulsion": {"D_prop_m": -1}}}')
    with pytest.raises(ParameterError) as err:
        FixedWingParams.load(f)
    text = str(err.value)
    assert "mass_kg = 0.0" in text and "C_ell_pp is not a parameter" in text and "D_prop_m = -1.0" in text
    assert "epsilon is no longer a parameter" in text


def test_one_axis_rate_models_approximate_the_coupled_modes(sim: Simulator) -> None:
    """The decoupled roll, short-period and Dutch-roll models (``rate_axes``, what the ArduPlane rate-loop design
    uses) have the exact linearisation's roll-subsidence pole and natural frequencies to a few per cent."""
    from fmu_models.fixed_wing.linear import lateral_modes, linearise, longitudinal_modes, rate_axes

    p = sim.params()
    lin = linearise(sim.model, p, trim(sim.model, p, 25.0))
    roll, dutch, _ = lateral_modes(lin)
    short, _ = longitudinal_modes(lin)
    ax = rate_axes(sim.model.params.view(p), 25.0)
    assert float(ax["roll"].a[0, 0]) == pytest.approx(roll.eigenvalues[0].real, rel=0.05)
    assert np.sqrt(np.linalg.det(ax["pitch"].a)) == pytest.approx(short.wn_rad_s, rel=0.05)
    assert np.sqrt(np.linalg.det(ax["yaw"].a)) == pytest.approx(dutch.wn_rad_s, rel=0.10)
    # positive aileron rolls right; positive (trailing-edge-down) elevator pitches the nose down
    assert ax["roll"].b[0] > 0 and ax["pitch"].b[1] < 0


def test_moment_from_rates_inverts_the_rate_equation() -> None:
    """``body_moments_N_m`` (equation error's regressand) is eq. 6 solved for the moment: feeding the rate
    derivative of ``rigid_body_derivatives`` back gives the moment that produced it."""
    import casadi as ca

    from fmu_models.common.rigid_body import body_moments_N_m, inertia_matrix, rigid_body_derivatives

    rng = np.random.default_rng(4)
    J = inertia_matrix(0.82, 1.14, 1.76, 0.12)
    for _ in range(5):
        w, m = rng.standard_normal(3), 3.0 * rng.standard_normal(3)
        wdot = rigid_body_derivatives(ca.DM.zeros(3), w, ca.DM([1, 0, 0, 0]), ca.DM.zeros(3), m, ca.DM.zeros(3),
                                      1.0, J)[3]
        got = body_moments_N_m(np.asarray(ca.DM(J)), w[None, :], np.asarray(wdot).T)
        assert np.allclose(got[0], m, atol=1e-12)
