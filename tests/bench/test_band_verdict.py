"""The band verdict's rule (``mc_bands.coverage_bounds``) on simulated replays of known coverage, through the
functions ``bench/band_verdict.py`` measures it with."""

from __future__ import annotations

import numpy as np
import pytest

from bench.band_verdict import findings, replays
from identification.validation.mc_bands import MAX_COVERAGE, band_position, coverage_bounds


def test_window_bounds_rarely_call_a_right_band_a_finding_and_show_a_wrong_one() -> None:
    """Simulated replays whose residuals drift within each window (AR(1), 0.98 from sample to sample): a right
    90 % band (|z| < 1.645) over 6 windows is past 80 % or 98 % by its point figure in about a fifth of the
    replays, but shown so in few; a band covering 60 % (|z| < 0.84) is shown below 80 % in most 20-window
    replays (0.9 from sample to sample); one covering 99.7 % (|z| < 3) is shown wide over 60 windows of less
    correlated samples."""
    rng = np.random.default_rng(1)
    low, wide, point = findings(replays(rng, 300, 6, 0.98), 1.645)
    assert point > 0.15 and low + wide <= 0.05, (low, wide, point)
    low, _, _ = findings(replays(rng, 300, 20, 0.9), 0.84)
    assert low >= 0.95, low
    _, wide, _ = findings(replays(rng, 300, 60, 0.5), 3.0)
    assert wide >= 0.90, wide
    # a band on the threshold (covering 98 %) is called wide no more often than the bound's 5 %
    _, wide, point = findings(replays(rng, 300, 20, 0.9), 2.326)
    assert point > 0.3 and wide <= 0.05, (wide, point)
    # one sample outside of 600: the indicator alone would count every sample as independent (a finding), the
    # position's correlation keeps the windows' weight
    z = replays(rng, 1, 12, 0.95)[0]
    z = z * (0.99 / np.abs(z).max())
    z[3, 10] = 1.2
    inside = (np.abs(z) < 1.0).ravel()
    win = np.repeat(np.arange(12), 50)
    assert coverage_bounds(inside, win).lower > MAX_COVERAGE  # the indicator's correlation: about 0
    b = coverage_bounds(inside, win, band_position(z.ravel(), np.full(600, -1.0), np.full(600, 1.0)))
    assert b.lower < MAX_COVERAGE and b.effective < 100, b
    one = coverage_bounds(np.zeros(50, bool), np.zeros(50, int))  # one window: it counts as one trial
    assert one.effective == pytest.approx(1.0) and one.windows == 1 and one.upper == pytest.approx(0.95)
