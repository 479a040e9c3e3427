"""The thrust map's parameter intervals on a known motor with white + AR(1) thrust noise (bench/thrust_coverage.py,
CI size): the stored covariance covers the truth at the 95 % level without being wider than twice the actual
scatter, where the lag-1 inflation of before covered about two thirds."""

from __future__ import annotations

import numpy as np

from bench.thrust_coverage import run_study


def test_thrust_map_intervals_cover_and_are_no_wider_than_the_scatter_allows() -> None:
    st = run_study(repeats=80, seed=200)
    cov, width = st.coverage(st.std), st.width_ratio(st.std)
    assert np.all(cov >= 0.88), cov  # 80 repeats of a true 0.95: below 0.88 with ~1 % chance
    assert np.all(width <= 2.0) and np.all(width >= 1.4), width  # 1.96 for an exact std
    # the lag-1 inflation sees only the first lag of the white + AR(1) residual: it covers far less
    assert np.all(st.coverage(st.std_lag1) < 0.8), st.coverage(st.std_lag1)
