"""The sensor low-pass in the output-error estimator: the continuous 2-pole Butterworth seen at the log's samples
(unit DC gain, low-frequency lag 2 zeta / wn = sqrt(2) / wc), applied to the model outputs it is given and to
their sensitivities (the filter is linear), and to nothing else."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import trim
from identification.estimation.oem import Manoeuvre, OutputErrorEstimator, sensor_lowpass

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
    model = FixedWingModel()
    p = np.array(model.params.starts())
    tr = trim(model, p, 25.0)
    n, dt = 150, 0.02
    u = np.tile(tr.u, (n, 1))
    u[20:40, 0] += 0.05
    u[40:60, 0] -= 0.05
    m = Manoeuvre(tr.x, u, np.zeros((n, len(OUTPUTS))), dt)
    free = ["C_ell_p", "C_ell_delta_a"]
    plain = OutputErrorEstimator(model, p, free, OUTPUTS, compile=False)
    filt = OutputErrorEstimator(model, p, free, OUTPUTS, compile=False, output_filters={"rate_body_x_rad_s": 20.0})
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
