"""The coverage study of ``identify aero``'s printed 95 % intervals (``bench/aero_coverage.py``: the demo's
synthetic generator with white + coloured noise and a mismatch in the FIXED coefficients, priors on and off; it must
reach 0.90 coverage and at most 2x the RMS error in half-width for every parameter, and exits 1 on a miss) is a
long Monte Carlo study and runs in bench/, not in CI. Here one repeat of it keeps its code path working and checks
what holds on every data set, not only on average."""

from __future__ import annotations

import numpy as np

from bench.aero_coverage import FREE, run_study


def test_one_repeat_of_the_coverage_study_bounds_every_derivative() -> None:
    st = run_study(repeats=1, seed=100, priors=True)
    assert st.values.shape == (1, len(FREE))
    assert np.all(np.isfinite(st.boot)), "block bootstrap over 8 manoeuvres must be computed"
    assert np.all(st.printed >= st.data - 1e-12)  # the consider share only widens the bound
    assert np.all(st.data >= st.crb - 1e-12)  # start errors and the small-sample bound only add
    # no estimate runs away from the truth: within 5 printed std (a 95 % interval is 1.96 std), every derivative
    assert np.all(np.abs(st.values - st.truth) <= 5.0 * st.printed), dict(
        zip(FREE, (np.abs(st.values - st.truth) / st.printed).round(2)[0], strict=True))
