"""Bounds that hold with a model mismatch in the FIXED coefficients: coverage of the printed
95 % intervals (data bound plus the consider covariance, after the auto-freeing round) on the demo's synthetic
generator with white + coloured noise, priors on (CI size; the 50-repeat study with priors on and off, which
must reach 0.90 for every parameter, is bench/aero_coverage.py)."""

from __future__ import annotations

import numpy as np

from bench.aero_coverage import FREE, run_study


def test_printed_intervals_cover_the_truth_with_fixed_parameter_mismatch() -> None:
    st = run_study(repeats=6, seed=100, priors=True)
    printed = st.coverage(st.printed)
    pooled = float(np.mean(np.abs(st.values - st.truth) <= 1.96 * st.printed))
    assert np.all(np.isfinite(st.boot)), "block bootstrap over 8 manoeuvres must be computed"
    assert np.all(st.printed >= st.data - 1e-12)  # the consider share only widens the bound
    # 72 intervals pooled: the 0.90 the bound claims (a true 0.95 falls below 0.90 here with ~5 % chance)
    assert pooled >= 0.90, dict(zip(FREE, printed, strict=True))
    assert np.min(printed) >= 4 / 6, dict(zip(FREE, printed, strict=True))
    # without the consider share the mismatch leaves some intervals short (the test can fail the other way)
    assert np.mean(np.abs(st.values - st.truth) <= 1.96 * st.crb) < pooled
    # and the bounds are not wildly wide: the printed std stays within 4x the scatter across repeats
    scatter = np.std(st.values - st.truth, axis=0, ddof=1)
    assert np.all(np.mean(st.printed, axis=0) < 4.0 * scatter), np.mean(st.printed, axis=0) / scatter
