"""The motor lag as the quadrotor estimator steps it: exact against the analytic first-order response."""

from __future__ import annotations

import dataclasses
import math

import casadi as ca
import numpy as np
import pytest

from fmu_models.common.model import init_function, step_function
from fmu_models.quadrotor.model import QuadrotorModel
from fmu_models.quadrotor.params import QuadrotorParams
from identification.estimation.oem import Manoeuvre, OutputErrorEstimator
from identification.quadrotor.identify import on_command_grid
from identification.quadrotor.motor_lag import ExactLagModel

DT_S = 0.004  # 250 Hz, the replica's and the shared SITL log's motor command rate


def _setup(model: QuadrotorModel) -> tuple[np.ndarray, np.ndarray]:
    p = np.array(model.params.starts(), dtype=float)
    p[model.params.index["init_pos_down_m"]] = -10.0  # airborne: no ground contact
    u0 = np.array(model.inputs.starts(), dtype=float)
    u0[:4] = 1400.0
    return p, u0


def _commanded(model: QuadrotorModel, u: np.ndarray, p: np.ndarray) -> float:
    return float(np.asarray(ca.DM(model.commanded_thrust(u, p)[0])).ravel()[0])


def _step_to_1600_us(model: QuadrotorModel) -> tuple:
    """The model's step function, its state at hover, every motor commanded to 1600 us, the parameters, and the
    thrust of motor 1 at the start and commanded [N]."""
    step, init = step_function(model), init_function(model)
    p, u0 = _setup(model)
    x = np.asarray(init(u0, p)[0]).ravel()
    u1 = u0.copy()
    u1[:4] = 1600.0
    return step, x, u1, p, x[16], _commanded(model, u1, p)


@pytest.mark.parametrize("tau_s", [0.001, 0.002, 0.005, 0.02])
def test_step_response_is_the_analytic_first_order_one(tau_s):
    params = dataclasses.replace(QuadrotorParams(), tau_motor_s=tau_s)
    step, x, u1, p, t_start, t_cmd = _step_to_1600_us(ExactLagModel(params, sample_s=DT_S))
    for k in range(1, 16):
        x = np.asarray(step(x, u1, p, DT_S)[0]).ravel()
        want = t_cmd + (t_start - t_cmd) * math.exp(-k * DT_S / tau_s)
        assert x[16] == pytest.approx(want, abs=1e-9 * abs(t_cmd - t_start))


def test_rk4_of_the_fmu_model_cannot_follow_a_lag_faster_than_its_step():
    """The reason for the exact model: the FMU's RK4 at the log's 4 ms step is 20 % off at tau = 2 ms."""
    params = dataclasses.replace(QuadrotorParams(), tau_motor_s=0.002)
    step, x, u1, p, t_start, t_cmd = _step_to_1600_us(QuadrotorModel(params))
    x = np.asarray(step(x, u1, p, DT_S)[0]).ravel()
    want = t_cmd + (t_start - t_cmd) * math.exp(-DT_S / 0.002)
    assert abs(x[16] - want) > 0.1 * abs(t_cmd - t_start)


def _fit_tau(model_cls: type, tau_true_s: float) -> float:
    """Output-error estimate of tau from the specific force of a hovering quadrotor whose four motors get PWM
    steps every 40 ms, the measurement made by the analytic first-order response (no drag, no rotation:
    ``a_z = -sum T / m``) with a little white noise."""
    truth = dataclasses.replace(QuadrotorParams(), tau_motor_s=tau_true_s, kd_z_N_s_m=0.0)
    start = dataclasses.replace(truth, tau_motor_s=0.01)
    model = model_cls(start, sample_s=DT_S) if model_cls is ExactLagModel else model_cls(start)
    p, u0 = _setup(model)
    n = 200
    pwm = np.where((np.arange(n) // 10) % 2 == 0, 1600.0, 1450.0)
    u = np.tile(u0, (n, 1))
    u[:, :4] = pwm[:, None]
    x0 = np.asarray(init_function(model)(u0, p)[0]).ravel()
    thrust, y = x0[16], np.empty((n, 1))
    decay = math.exp(-DT_S / tau_true_s)
    for k in range(n):
        c = _commanded(model, u[k], p)
        thrust = c + (thrust - c) * decay
        y[k, 0] = -4.0 * thrust / truth.mass_kg
    y += np.random.default_rng(1).normal(0.0, 1e-3, y.shape)
    oe = OutputErrorEstimator(model, p, ["tau_motor_s"], ["accel_body_z_m_s2"], bounds={"tau_motor_s": (1e-4, 0.3)},
                              compile=False)
    return float(oe.estimate([Manoeuvre(x0, u, y, DT_S)], max_iter=40).values[0])


@pytest.mark.parametrize("tau_s", [0.0015, 0.003, 0.02])
def test_fitted_time_constant_is_unbiased_against_the_analytic_response(tau_s):
    assert _fit_tau(ExactLagModel, tau_s) == pytest.approx(tau_s, rel=1e-3)


def test_fitted_time_constant_of_the_rk4_model_is_biased_at_small_truths():
    """The same fit through the FMU's RK4 step misses a 3 ms motor by more than 10 % (the bias removed)."""
    assert abs(_fit_tau(QuadrotorModel, 0.003) / 0.003 - 1.0) > 0.10


def test_records_start_on_a_motor_command_sample():
    t = np.arange(0, 1, DT_S)
    assert on_command_grid(t, 0.4) == pytest.approx(0.4)
    assert on_command_grid(t, 0.4025) == pytest.approx(0.404)  # between samples: the next one
    assert on_command_grid(t, 5.0) == 5.0  # past the log: unchanged


@pytest.mark.parametrize("tau_s", [0.0008, 0.002, 0.02])
def test_body_rates_follow_a_fast_motor_as_a_fine_integration_does(tau_s):
    """One motor stepped up from hover: the body rates after 1-5 steps of 4 ms match RK4 at 0.05 ms within
    0.5 % of their change (the thrust's impulse over each step is exact, also for a motor five times faster than
    the step, where RK4's own weights overstate it by 10 %)."""
    params = dataclasses.replace(QuadrotorParams(), tau_motor_s=tau_s)
    exact, fine = ExactLagModel(params, sample_s=DT_S), QuadrotorModel(params)
    step_e, step_f = step_function(exact), step_function(fine)
    p, u0 = _setup(exact)
    x_e = x_f = np.asarray(init_function(exact)(u0, p)[0]).ravel()
    u1 = u0.copy()
    u1[0] = 1600.0
    rates = slice(10, 13)  # body rates in the state vector
    for _ in range(5):
        x_e = np.asarray(step_e(x_e, u1, p, DT_S)[0]).ravel()
        for _ in range(80):
            x_f = np.asarray(step_f(x_f, u1, p, DT_S / 80)[0]).ravel()
        assert np.abs(x_e[rates] - x_f[rates]).max() <= 5e-3 * np.abs(x_f[rates]).max()
