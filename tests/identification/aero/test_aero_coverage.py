"""Bounds that hold with a model mismatch in the FIXED coefficients: coverage and width of the printed
95 % intervals (AR data bound plus the consider covariance, after the auto-freeing rounds) on the demo's synthetic
generator with white + coloured noise, priors on (CI size; the study with priors on and off, which must reach
0.90 coverage and at most 2x the RMS error in half-width for every parameter, is bench/aero_coverage.py)."""

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
    # the mismatched coefficients the data inform are freed (C_L_q, which held fixed moved C_m_q by about two
    # data std, among them): the AR Cramer-Rao bound alone covers as well as the printed one
    assert np.mean(np.abs(st.values - st.truth) <= 1.96 * st.crb) >= 0.90
    # and the bounds are no wider than the data justify: the median 95 % half-width within 3x the RMS error
    # (1.96 for an exact std; the bootstrap bound of before reached 2.6-6x on the 12-repeat study)
    width = st.width_ratio(st.printed)
    assert np.all(width <= 3.0), dict(zip(FREE, width.round(2), strict=True))
