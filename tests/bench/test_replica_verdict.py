"""The replica benches' Monte Carlo verdicts: a right interval is seldom called a miss, a wrong one usually is."""

from __future__ import annotations

import numpy as np

from bench.replica_verdict import coverage_figure, width_figure


def test_coverage_verdicts_follow_the_binomial_bound():
    assert coverage_figure(np.array([True] * 19 + [False]), 0.90).verdict == "met"
    assert coverage_figure(np.array([True] * 17 + [False] * 3), 0.90).verdict == "unresolved"  # upper 0.96
    assert coverage_figure(np.array([True] * 14 + [False] * 6), 0.90).verdict == "miss"  # upper 0.87


def _miss_rate(scale: float, target: float, stat: str, runs: int = 200, draws: int = 20) -> float:
    rng = np.random.default_rng(1)
    hits = 0
    for _ in range(runs):
        sd = rng.uniform(0.5, 2.0, draws)  # each draw its own std, as random truths have
        err = rng.normal(0.0, sd) / sd  # standardised: the ratio is about the interval's calibration
        hits += width_figure(np.full(draws, 1.96 * scale), err, target, stat=stat).verdict == "miss"
    return hits / runs


def test_a_right_interval_is_seldom_a_shown_miss_and_a_wide_one_usually_is():
    assert _miss_rate(1.0, 2.0, "rms") <= 0.10  # measured 0.03
    assert _miss_rate(1.0, 3.0, "median") <= 0.10  # measured 0.03
    assert _miss_rate(1.6, 2.0, "rms") >= 0.5  # measured 0.80
    assert _miss_rate(2.0, 3.0, "median") >= 0.5  # measured 0.82: the median of 20 errors is a blunt scale


def test_per_draw_widths_take_each_draw_in_its_own_units():
    """Draws whose interval scales differ by 100x: a right interval reads about 1.96 over the rms error in its own
    units, while the plain ratio of unlike draws is set by the widest ones' errors and reads far below it."""
    from bench.replica_verdict import draw_width_figure

    rng = np.random.default_rng(5)
    sd = np.exp(rng.uniform(np.log(0.01), np.log(1.0), 400))
    err = rng.normal(0.0, sd)
    per_draw = draw_width_figure(1.96 * sd, err, 2.0, stat="rms")
    plain = width_figure(1.96 * sd, err, 2.0, stat="rms")
    assert abs(per_draw.value - 1.96) < 0.2 and per_draw.verdict == "met"
    assert plain.value < 1.0  # the median width of unlike draws over the rms of their errors
    assert draw_width_figure(0.5 * 1.96 * sd, err, 2.0).verdict == "met"  # narrower reads lower...
    assert coverage_figure(np.abs(err) <= 0.5 * 1.96 * sd, 0.90).verdict == "miss"  # ...and coverage shows it
