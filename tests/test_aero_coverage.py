"""Issue 18 bounds that hold: coverage of the printed 95 % intervals on the demo's synthetic generator with
white + coloured noise and a small model mismatch (CI size; the 50-repeat study is bench/aero_coverage.py)."""

from __future__ import annotations

import numpy as np

from bench.aero_coverage import FREE, run_study


def test_printed_intervals_cover_the_truth_in_a_small_monte_carlo() -> None:
    st = run_study(repeats=10, seed=100)
    printed = st.coverage(st.printed)
    assert np.all(np.isfinite(st.boot)), "block bootstrap over 8 manoeuvres must be computed"
    assert np.all(st.printed >= st.crb - 1e-15) and np.all(st.printed >= st.boot - 1e-15)
    assert np.mean(printed) >= 0.88, dict(zip(FREE, printed, strict=True))
    assert np.min(printed) >= 0.7, dict(zip(FREE, printed, strict=True))
    # the bounds are neither wildly wide: the printed std stays within 2x the scatter across repeats
    scatter = np.std(st.values - st.truth, axis=0, ddof=1)
    assert np.all(np.mean(st.printed, axis=0) < 2.0 * scatter)
