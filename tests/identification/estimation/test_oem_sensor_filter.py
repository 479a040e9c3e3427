"""The sensor low-pass in the output-error estimator: the continuous 2-pole Butterworth seen at the log's samples
(unit DC gain, low-frequency lag 2 zeta / wn = sqrt(2) / wc), applied to the model outputs it is given and to
their sensitivities (the filter is linear), and to nothing else; run at integration sub-steps short enough that
the curvature of the output between samples no longer biases the fit (the filter runs at the IMU rate)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from identification.estimation.oem import (
    EstimationError,
    Manoeuvre,
    OutputErrorEstimator,
    filter_substeps,
    sensor_lowpass,
)
from tests.fakes.aileron_steps import trimmed_aileron_steps

OUTPUTS = ["roll_rad", "rate_body_x_rad_s", "accel_body_y_m_s2"]


@pytest.mark.parametrize("fc, dt", [(20.0, 0.02), (5.0, 0.01), (30.0, 0.004)])
def test_lowpass_has_unit_gain_and_the_butterworth_lag(fc: float, dt: float) -> None:
    b, a, zi = sensor_lowpass(fc, dt)
    assert b.sum() / a.sum() == pytest.approx(1.0)
    t = np.arange(2000) * dt
    y = lfilter(b, a, t, zi=zi * 0.0)[0]
    assert (t - y)[-1] == pytest.approx(math.sqrt(2.0) / (2 * math.pi * fc), rel=0.01)  # ramp lag
    assert np.allclose(lfilter(b, a, np.full(50, 3.0), zi=zi * 3.0)[0], 3.0)  # steady start stays steady


def test_filtered_outputs_and_sensitivities() -> None:
    n, dt = 150, 0.02
    model, p, tr, u = trimmed_aileron_steps(n, [(20, 40, 0.05), (40, 60, -0.05)])
    m = Manoeuvre(tr.x, u, np.zeros((n, len(OUTPUTS))), dt)
    free = ["C_ell_p", "C_ell_delta_a"]
    plain = OutputErrorEstimator(model, p, free, OUTPUTS, compile=False)
    filt = OutputErrorEstimator(model, p, free, OUTPUTS, compile=False, output_filters={"rate_body_x_rad_s": 20.0},
                                substeps=1)
    theta = p[plain.i_free]
    y0, _, _ = plain.simulate(theta, m)
    y1, j1, _ = filt.simulate(theta, m)
    b, a, zi = sensor_lowpass(20.0, dt)
    assert np.allclose(y1[:, 1], lfilter(b, a, y0[:, 1], zi=zi * y0[0, 1])[0])
    assert np.array_equal(y1[:, [0, 2]], y0[:, [0, 2]])  # only the named output is filtered
    assert np.abs(y1[:, 1] - y0[:, 1]).max() > 1e-3  # and the filter matters on an aileron doublet
    h = 1e-6 * abs(theta[0])  # sensitivities of the filtered output: finite differences of the filtered model
    step = np.array([h, 0.0])
    up = filt.simulate(theta + step, m, sensitivities=False)[0]
    dn = filt.simulate(theta - step, m, sensitivities=False)[0]
    assert np.allclose(j1[:, 1, 0], (up[:, 1] - dn[:, 1]) / (2 * h), rtol=1e-4, atol=1e-8)
    with pytest.raises(ValueError, match="filtered output 'airspeed_m_s'"):
        OutputErrorEstimator(model, p, free, OUTPUTS, compile=False, output_filters={"airspeed_m_s": 5.0})


def test_filter_substeps_rule() -> None:
    assert filter_substeps(0.0, 0.02) == 1  # no filter: one RK4 step per sample
    assert filter_substeps(20.0, 0.02) == 6  # 2 pi 20 Hz 20 ms = 2.51 rad -> 0.42 rad per sub-step
    assert filter_substeps(20.0, 0.0025) == 1  # 400 Hz samples: 0.31 rad already
    assert filter_substeps(1e6, 0.02) == 64  # bounded
    model = FixedWingModel()
    p = np.array(model.params.starts())
    assert OutputErrorEstimator(model, p, ["C_ell_p"], OUTPUTS, compile=False).substeps_for(0.02) == 1
    filt = OutputErrorEstimator(model, p, ["C_ell_p"], OUTPUTS, compile=False,
                                output_filters={"rate_body_x_rad_s": 20.0})
    assert filt.substeps_for(0.02) == 6
    with pytest.raises(EstimationError, match="substeps 0"):
        OutputErrorEstimator(model, p, ["C_ell_p"], OUTPUTS, compile=False, substeps=0)


def _filtered_plant(model: FixedWingModel, p: np.ndarray, x0: np.ndarray, u: np.ndarray, dt: float, sub: int,
                    fc: float) -> np.ndarray:
    """Roll and roll rate at the samples of a plant stepped ``sub`` times per sample, its gyro low-passed at
    that rate (the replica bench's chain, independent of the estimator's code)."""
    n = len(u)
    _, _, y = Simulator(model).run(lambda t: u[min(int(t / dt + 1e-9), n - 1)], p, n * dt, dt / sub, x0=x0)
    idx = model.outputs.index
    roll, rate = y[:, idx["roll_rad"]], y[:, idx["rate_body_x_rad_s"]]
    b, a, zi = sensor_lowpass(fc, dt / sub)
    rate = lfilter(b, a, rate, zi=zi * rate[0])[0]
    return np.column_stack([roll[sub::sub][:n], rate[sub::sub][:n]])


def test_substeps_remove_the_filter_discretisation_bias() -> None:
    """Noise-free roll doublets at 50 Hz through a 20 Hz gyro filter run at 1 kHz: fitted with the filter at the
    log step, C_ell_p comes out biased by about 1 %; with the default sub-steps within 0.1 %."""
    n, dt, fc = 200, 0.02, 20.0
    model, p, tr, u = trimmed_aileron_steps(n, [(k0, k0 + 10, 0.05 * sign)
                                                for k0, sign in ((20, 1.0), (30, -1.0), (100, -1.0), (110, 1.0))])
    y = _filtered_plant(model, p, tr.x, u, dt, 20, fc)
    data = [Manoeuvre(tr.x, u, y, dt)]
    free, outputs = ["C_ell_p", "C_ell_delta_a"], ["roll_rad", "rate_body_x_rad_s"]
    weight = np.diag([1 / 0.003 ** 2, 1 / 0.005 ** 2])
    err = {}
    for k in (1, None):
        oe = OutputErrorEstimator(model, p, free, outputs, compile=False, substeps=k,
                                  output_filters={"rate_body_x_rad_s": fc})
        est = oe.estimate(data, theta0=p[oe.i_free] * 1.05, weight=weight, max_iter=30)
        err[k] = est.values[:2] / p[oe.i_free] - 1.0
    assert np.max(np.abs(err[1])) > 0.005, err  # at the log step the curvature between samples leaks through
    assert np.max(np.abs(err[None])) < 0.001, err


def test_substep_sensitivities_are_the_derivatives_of_the_substepped_outputs() -> None:
    n, dt = 60, 0.02
    model, p, tr, u = trimmed_aileron_steps(n, [(10, 20, 0.05)])
    m = Manoeuvre(tr.x, u, np.zeros((n, len(OUTPUTS))), dt)
    oe = OutputErrorEstimator(model, p, ["C_ell_p", "C_ell_delta_a"], OUTPUTS, compile=False, substeps=4,
                              output_filters={"rate_body_x_rad_s": 20.0, "accel_body_y_m_s2": 20.0})
    theta = p[oe.i_free]
    y, jac, bad = oe.simulate(theta, m)
    assert not bad and y.shape == (n, len(OUTPUTS)) and jac.shape == (n, len(OUTPUTS), 2)
    assert np.allclose(oe.simulate(theta, m, sensitivities=False)[0], y)
    h = 1e-6 * abs(theta[0])
    step = np.array([h, 0.0])
    fd = (oe.simulate(theta + step, m, sensitivities=False)[0] - oe.simulate(theta - step, m, sensitivities=False)[0])
    assert np.allclose(jac[:, :, 0], fd / (2 * h), rtol=1e-4, atol=1e-8)
