"""Fit metrics against values computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from identification.metrics import MetricsError, fit_metrics


def test_hand_computed_example() -> None:
    y = np.array([1.0, 2.0, 3.0, 4.0])
    m = np.array([1.0, 2.0, 3.0, 5.0])
    f = fit_metrics(y, m)
    assert f.rmse == pytest.approx(0.5)  # sqrt(1/4)
    assert f.nrmse == pytest.approx(0.5 / 3.0)
    assert f.theil_u == pytest.approx(0.5 / (math.sqrt(7.5) + math.sqrt(39 / 4)))
    assert f.r2 == pytest.approx(1 - 1 / 5.0)  # SS_res 1, SS_tot 5
    assert f.fit_percent == pytest.approx(100 * (1 - 1 / math.sqrt(5)))
    assert f.max_error == 1.0 and f.n == 4


def test_perfect_fit_and_nan_dropping() -> None:
    y = np.array([0.0, 1.0, np.nan, 2.0])
    f = fit_metrics(y, np.array([0.0, 1.0, 5.0, 2.0]))
    assert f.rmse == 0.0 and f.theil_u == 0.0 and f.r2 == 1.0 and f.fit_percent == 100.0 and f.n == 3


def test_mismatched_lengths_are_an_error() -> None:
    with pytest.raises(MetricsError, match="3 samples, model 2"):
        fit_metrics(np.zeros(3), np.zeros(2))


def test_segment_metrics_equal_fit_metrics_per_segment() -> None:
    from identification.metrics import segment_metrics

    rng = np.random.default_rng(4)
    y = np.cumsum(rng.normal(size=503))
    m = y + rng.normal(0, 0.3, size=503)
    m[100] = np.nan  # a segment with a NaN falls back to the exact per-segment path
    starts = np.array([0, 50, 97, 260, 500])
    got = segment_metrics(y, m, starts)
    ends = [*starts[1:], 503]
    for s, e, g in zip(starts, ends, got, strict=True):
        want = fit_metrics(y[s:e], m[s:e])
        for field in ("rmse", "nrmse", "theil_u", "fit_percent", "r2", "max_error"):
            assert getattr(g, field) == pytest.approx(getattr(want, field), rel=1e-9, abs=1e-12), (s, field)
        assert g.n == want.n
