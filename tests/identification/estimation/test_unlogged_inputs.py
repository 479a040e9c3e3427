"""Commands of unlogged loops estimated from the response: servo outputs logged every second 50 Hz loop (as
ArduPlane's 25 Hz RCOU task), aileron steps in unlogged loops. The mean of the neighbours is half a step off
at each such loop; estimated at the true parameters, every unlogged command comes back to its true value."""

from __future__ import annotations

import numpy as np

from identification.estimation.oem import Manoeuvre, OutputErrorEstimator
from identification.estimation.unlogged_inputs import Unlogged, fit_with_unlogged, profiled_std, refine_unlogged
from identification.logs.sensor_chain import LoopClock
from tests.fakes.aileron_steps import trimmed_aileron_steps

OUTPUTS = ["roll_rad", "rate_body_x_rad_s", "rate_body_z_rad_s", "accel_body_y_m_s2"]


def test_unlogged_steps_come_back_and_widen_the_bound() -> None:
    dt, n = 0.02, 100
    # steps at loops 11, 27 and 41: unlogged (the log task runs at even loops)
    model, p, tr, u = trimmed_aileron_steps(n, [(11, 27, 0.05), (27, 41, -0.05)])
    i_ail = list(model.inputs.index).index("aileron_rad")
    oe = OutputErrorEstimator(model, p, ["C_ell_p", "C_ell_delta_a"], OUTPUTS)
    theta = p[oe.i_free]
    y = oe.simulate(theta, Manoeuvre(tr.x, u, np.zeros((n, len(OUTPUTS))), dt), 0, sensitivities=False)[0]
    ticks = np.arange(n) * dt
    clock = LoopClock(ticks, dt)
    cols = [clock.bracket(ticks[::2], u[::2, c], ticks) for c in range(u.shape[1])]
    before, after, share, logged = (np.column_stack(x) for x in zip(*cols, strict=True))
    mean = before + share * (after - before)
    steps = [11, 27, 41]
    assert np.allclose(np.abs(mean[steps, i_ail] - u[steps, i_ail]), [0.025, 0.05, 0.025])
    br = Unlogged(before, after, logged)
    assert sorted(k for k, c in br.free()) == steps  # equal neighbours pin every other unlogged loop
    weight = np.diag([1 / 0.01 ** 2, 1 / 0.01 ** 2, 1 / 0.01 ** 2, 1 / 0.2 ** 2])
    refined = refine_unlogged(oe, theta, [Manoeuvre(tr.x, mean, y, dt)], [br], weight)[0]
    assert np.max(np.abs(refined.u - u)) < 0.05 * 0.05
    plain = profiled_std(oe, theta, [refined], [Unlogged(before, after, np.ones_like(logged))], weight)
    profiled = profiled_std(oe, theta, [refined], [br], weight)
    assert np.all(profiled > plain * 1.0001)


def test_profiled_fit_converges_to_the_truth_from_the_mean_commands() -> None:
    """Noise-free: the fit with the neighbours' mean is off in both roll derivatives; estimating the unlogged
    commands with the parameters (profiled Gauss-Newton steps) brings both back to the truth and every command
    to its value, where 4 rounds of alternating command and parameter fits stopped 3.4 % off."""
    dt, n = 0.02, 150
    # steps at odd (unlogged) loops
    model, p, tr, u = trimmed_aileron_steps(n, [(11, 27, 0.05), (27, 41, -0.05), (81, 95, -0.04), (95, 109, 0.04)])
    free = ["C_ell_p", "C_ell_delta_a"]
    oe = OutputErrorEstimator(model, p, free, OUTPUTS)
    y = oe.simulate(p[oe.i_free], Manoeuvre(tr.x, u, np.zeros((n, len(OUTPUTS))), dt), 0, sensitivities=False)[0]
    ticks = np.arange(n) * dt
    clock = LoopClock(ticks, dt)
    cols = [clock.bracket(ticks[::2], u[::2, c], ticks) for c in range(u.shape[1])]
    before, after, share, logged = (np.column_stack(x) for x in zip(*cols, strict=True))
    data = [Manoeuvre(tr.x, before + share * (after - before), y, dt)]
    brackets = [Unlogged(before, after, logged)]
    weight = np.diag([1 / 0.01 ** 2, 1 / 0.01 ** 2, 1 / 0.01 ** 2, 1 / 0.2 ** 2])
    truth = p[oe.i_free]
    mean_fit = oe.estimate(data, theta0=truth, weight=weight)
    assert np.max(np.abs(mean_fit.values[:2] / truth - 1)) > 0.01  # half steps one loop off bias the fit
    est, used = fit_with_unlogged(oe, data, brackets, weight, start=mean_fit)
    assert np.max(np.abs(est.values[:2] / truth - 1)) < 1e-3
    assert np.max(np.abs(used[0].u - u)) < 0.02 * 0.05
    pinned = brackets[0].pinned(used[0].u)  # every step's command is a neighbour's: none left inside
    assert pinned.free() == [] and len(brackets[0].free()) == 6
