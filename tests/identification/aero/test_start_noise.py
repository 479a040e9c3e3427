"""The error of a segment's start state read from a noisy log, and what it does to the derivatives' bounds: the
signals' noise read from the log, its covariance carried into the model's states, the estimate's shift per unit
start error (checked against a refit), and the small-sample test expecting the scatter it brings."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fmu_models.common.model import init_function
from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import trim
from identification.aero.model import start_covariance, start_noise
from identification.estimation.oem import (
    BOUND_METHODS,
    Manoeuvre,
    OutputErrorEstimator,
    data_bound,
    small_sample_needed,
    start_consider_covariance,
    student_factor,
)
from identification.flights.synthetic import multistep
from identification.logs.flightlog import FlightLog, Signal
from identification.logs.log_state import NOISE_MIN_SAMPLES, interpolation_variance_factor, noise_std

RATE_HZ = 50.0


def _signal(name: str, t: np.ndarray, v: np.ndarray, unit: str = "") -> Signal:
    return Signal(name, t, np.asarray(v, float), unit)


def test_noise_std_reads_white_noise_under_a_manoeuvre_and_nothing_from_a_held_signal() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 60.0, 1.0 / RATE_HZ)
    motion = 0.3 * np.sin(2 * np.pi * 0.5 * t) + 0.2 * (t % 10 > 5)  # a sine and a few steps
    noisy = _signal("roll_rad", t, motion + rng.normal(0.0, 0.01, t.size), "rad")
    windows = [(5.0, 25.0), (30.0, 55.0)]
    assert noise_std(noisy, windows) == pytest.approx(0.01, rel=0.1)
    # a signal logged at 5 Hz and held between: no noise to read, not its steps read as noise
    held = _signal("altitude_m", t, np.repeat(rng.normal(0.0, 1.0, t.size // 10 + 1), 10)[:t.size])
    assert noise_std(held, windows) == 0.0
    # too few samples inside the windows
    assert noise_std(noisy, [(1.0, 1.0 + (NOISE_MIN_SAMPLES - 5) / RATE_HZ)]) == 0.0
    # yaw across the +-pi seam: the wrap is not noise
    yaw = np.angle(np.exp(1j * (np.pi - 0.05 + 0.01 * t))) + rng.normal(0.0, 0.002, t.size)
    assert noise_std(_signal("yaw_rad", t, yaw, "rad"), windows) == pytest.approx(0.002, rel=0.15)


def test_interpolated_value_has_the_variance_of_its_two_weights() -> None:
    sig = _signal("x", np.array([0.0, 1.0, 2.0]), np.zeros(3))
    assert interpolation_variance_factor(sig, 1.0) == pytest.approx(1.0)
    assert interpolation_variance_factor(sig, 1.5) == pytest.approx(0.5)
    assert interpolation_variance_factor(sig, 0.25) == pytest.approx(0.75 ** 2 + 0.25 ** 2)


def _level_log(va: float = 25.0) -> FlightLog:
    """Level flight due north at ``va`` m/s and 100 m, every signal a start is read from logged at 50 Hz."""
    t = np.arange(0.0, 10.0, 1.0 / RATE_HZ)
    one = np.ones_like(t)
    sig = {"roll_rad": 0 * one, "pitch_rad": 0 * one, "yaw_rad": 0 * one, "gyro_body_x_rad_s": 0 * one,
           "gyro_body_y_rad_s": 0 * one, "gyro_body_z_rad_s": 0 * one, "vel_north_m_s": va * one,
           "vel_east_m_s": 0 * one, "vel_down_m_s": 0 * one, "airspeed_m_s": va * one, "altitude_m": 100 * one}
    return FlightLog("level", "synthetic", {n: _signal(n, t, v, "rad" if n.endswith("_rad") else "")
                                            for n, v in sig.items()}, {}, "fixed_wing")


def test_start_covariance_carries_each_signals_noise_into_the_states() -> None:
    model = FixedWingModel()
    p = np.array(model.params.starts(), float)
    log, st = _level_log(25.0), model.states.index
    init, u0 = init_function(model), np.zeros(len(model.inputs.index))
    # the pitch noise turns the forward speed into the vertical body velocity: w = -V sin(theta) near level
    c = start_covariance(model, p, log, 2.0, u0, {"pitch_rad": 0.003}, init)
    assert np.sqrt(c[st["vel_body_z_m_s"], st["vel_body_z_m_s"]]) == pytest.approx(25.0 * 0.003, rel=1e-3)
    assert np.sqrt(c[st["quat_y"], st["quat_y"]]) == pytest.approx(0.003 / 2, rel=1e-3)  # q_y = sin(theta / 2)
    assert c[st["vel_body_x_m_s"], st["vel_body_x_m_s"]] < 1e-9
    assert c[st["pos_down_m"], st["pos_down_m"]] == 0.0
    # the altitude's noise, read midway between two samples: half the variance of one sample
    c = start_covariance(model, p, log, 2.01, u0, {"altitude_m": 0.1}, init)
    assert c[st["pos_down_m"], st["pos_down_m"]] == pytest.approx(0.5 * 0.1 ** 2, rel=1e-3)
    # the noise is read from the log: one entry per signal a start is read from (the GPS velocity, so not the
    # airspeed)
    noise = start_noise(log, [(0.0, 10.0)])
    assert set(noise) == {"roll_rad", "pitch_rad", "yaw_rad", "gyro_body_x_rad_s", "gyro_body_y_rad_s",
                          "gyro_body_z_rad_s", "vel_north_m_s", "vel_east_m_s", "vel_down_m_s", "altitude_m"}
    assert all(v == 0.0 for v in noise.values())  # a noise-free log


FREE = ["C_ell_p", "C_ell_delta_a", "C_n_r", "C_n_delta_r"]
OUTPUTS = ["roll_rad", "rate_body_x_rad_s", "rate_body_z_rad_s", "accel_body_y_m_s2"]
SIGMA = np.array([0.005, 0.005, 0.005, 0.05])
STATE = "vel_body_y_m_s"
N = 300  # 6 s


@pytest.fixture(scope="module")
def problem() -> tuple[Simulator, np.ndarray, list[Manoeuvre]]:
    """Three lateral manoeuvres from their exact starts, noise-free: the estimate sits at the truth with no residual,
    where the consider covariance's Gauss-Newton shift is the estimate's exact derivative (with noise, the
    residual's curvature term it leaves out, as every consider analysis does, moved one derivative by 18 %)."""
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    plant = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, compile=False)
    data = []
    for j, va in enumerate((22.0, 25.0, 28.0)):
        tr = trim(sim.model, p, va)
        t = np.arange(N) / RATE_HZ
        u = np.tile(tr.u, (N, 1))
        u[:, 0] += multistep(t, 0.5 + 0.3 * j, 0.4, 0.05)
        u[:, 2] += multistep(t, 3.0, 0.4, 0.05)
        y = plant.simulate(p[plant.i_free], Manoeuvre(tr.x, u, np.zeros((N, len(OUTPUTS))), 1 / RATE_HZ),
                           sensitivities=False)[0]
        data.append(Manoeuvre(np.array(tr.x, float), u, y, 1 / RATE_HZ, f"trim {va} m/s"))
    return sim, p, data


def test_start_consider_covariance_is_the_refits_shift_per_start_error(problem) -> None:
    """A start error of one manoeuvre moves the estimate as the consider covariance says: refits with that
    manoeuvre's side velocity started 0.01 m/s above and below give, per m/s, the std the covariance gives a start
    error of 1 m/s std; a state the estimator fits per manoeuvre takes the error up."""
    sim, p, data = problem
    weight = np.diag(1.0 / SIGMA ** 2)
    oe = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, compile=False)
    est = oe.estimate(data, weight=weight, max_iter=40)
    nx, iv, dv = len(sim.model.states.index), sim.model.states.index[STATE], 0.01
    covs = [np.zeros((nx, nx)) for _ in data]
    covs[1][iv, iv] = 1.0
    cov = start_consider_covariance(oe, est, data, covs, weight)
    refits = []
    for sign in (1.0, -1.0):
        x0 = data[1].x0.copy()
        x0[iv] += sign * dv
        moved = [*data[:1], dataclasses.replace(data[1], x0=x0), *data[2:]]
        refits.append(oe.estimate(moved, theta0=est.values, weight=weight, max_iter=40, tol=1e-14).values)
    per_m_s = np.abs(refits[0] - refits[1]) / (2 * dv)
    assert per_m_s.min() > 1e-4  # the start error moves every derivative: the test is not about zeros
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), per_m_s, rtol=0.01)
    # the side velocity estimated per manoeuvre: its start error is taken up, nothing to consider
    free_v = OutputErrorEstimator(sim.model, p, FREE, OUTPUTS, compile=False, estimate_states=[STATE])
    est_v = free_v.estimate(data, weight=weight, max_iter=40)
    assert np.all(start_consider_covariance(free_v, est_v, data, covs, weight) == 0.0)
    with pytest.raises(Exception, match="2 start covariances for 3 manoeuvres"):
        start_consider_covariance(oe, est, data, covs[:2], weight)


def test_the_start_share_adds_to_the_bound_and_the_scatter_test_expects_it() -> None:
    crb, boot, dof = np.array([1.0, 1.0]), np.array([1.0, 1.0]), np.array([8.0, 8.0])
    scatter = (np.array([2.5, 2.5]), np.array([8.0, 8.0]))  # 2.5x the scatter the residual model expects
    ar = BOUND_METHODS[2]
    # without the start share the segments scatter significantly more (chi2_0.95(8)/8 = 1.94 < 2.5): small sample
    assert small_sample_needed(crb, boot, dof, scatter).all()
    wide = data_bound(crb, boot, dof, 9, ar, scatter)
    assert np.all(wide > np.sqrt(2.5))
    # start errors that account for that scatter (crb^2 + 1.5 = 2.5 crb^2): the test does not fire, and the bound
    # is the coloured one and the start share in quadrature
    start = np.array([1.5, 0.2])
    assert small_sample_needed(crb, boot, dof, scatter, start).tolist() == [False, True]
    bound = data_bound(crb, boot, dof, 9, ar, scatter, start)
    assert bound[0] == pytest.approx(np.sqrt(2.5))
    assert bound[1] == pytest.approx(wide[1])  # where it still fires, the measured scatter holds the starts'
    assert data_bound(crb, None, None, 9, ar, None, start) == pytest.approx(np.sqrt(crb ** 2 + start))
    # a scatter that already expects each segment's start error (segment_scatter with its shifts) is taken as it
    # is, and the small-sample bound scales the coloured bound and the start share together
    assert small_sample_needed(crb, boot, dof, scatter, start, start_in_scatter=True).all()
    carried = data_bound(crb, boot, dof, 9, ar, scatter, start, start_in_scatter=True)
    assert carried == pytest.approx(np.sqrt((crb ** 2 + start) * 2.5) * student_factor(8.0))


def test_the_cli_turns_the_start_noise_off_and_the_default_keeps_it() -> None:
    import argparse

    from identification.aero.identify import AeroOptions
    from uavfmu.commands import identify_aero as cmd

    parser = argparse.ArgumentParser()
    cmd.add_arguments(parser)
    assert AeroOptions().start_noise
    assert cmd._options(parser.parse_args(["x.BIN", "--out", "x.json"])).start_noise
    assert not cmd._options(parser.parse_args(["x.BIN", "--out", "x.json", "--no-start-noise"])).start_noise
