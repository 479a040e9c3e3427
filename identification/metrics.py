"""Fit metrics of a model output against a measurement (flight-test identification conventions)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


class MetricsError(ValueError):
    """Mismatched or empty series."""


@dataclass(frozen=True)
class FitMetrics:
    """RMSE [signal unit], NRMSE (RMSE / range of the measurement), Theil inequality coefficient U
    (0 perfect, 1 useless; < 0.3 is the usual acceptance bar), fit percent (100 (1 - |e| / |y - mean y|)),
    coefficient of determination R^2, largest absolute error, and the number of samples."""

    rmse: float
    nrmse: float
    theil_u: float
    fit_percent: float
    r2: float
    max_error: float
    n: int

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def fit_metrics(measured: np.ndarray, model: np.ndarray) -> FitMetrics:
    """Metrics of ``model`` against ``measured`` (same length, NaNs in either dropped)."""
    y = np.asarray(measured, dtype=float).ravel()
    m = np.asarray(model, dtype=float).ravel()
    if y.shape != m.shape:
        raise MetricsError(f"measured has {y.size} samples, model {m.size}: they must match")
    keep = np.isfinite(y) & np.isfinite(m)
    y, m = y[keep], m[keep]
    if y.size == 0:
        raise MetricsError("no sample where both measured and model values are finite")
    e = y - m
    rmse = float(np.sqrt(np.mean(e**2)))
    span = float(np.ptp(y))
    dev = y - y.mean()
    den_theil = float(np.sqrt(np.mean(y**2)) + np.sqrt(np.mean(m**2)))
    ss_tot = float(np.sum(dev**2))
    return FitMetrics(
        rmse=rmse,
        nrmse=rmse / span if span > 0 else float("inf"),
        theil_u=rmse / den_theil if den_theil > 0 else 0.0,
        fit_percent=100.0 * (1.0 - np.linalg.norm(e) / np.linalg.norm(dev)) if ss_tot > 0 else float("-inf"),
        r2=1.0 - float(np.sum(e**2)) / ss_tot if ss_tot > 0 else float("-inf"),
        max_error=float(np.max(np.abs(e))),
        n=int(y.size),
    )


def segment_metrics(measured: np.ndarray, model: np.ndarray, starts: np.ndarray) -> list[FitMetrics]:
    """:func:`fit_metrics` of each segment ``[starts[i], starts[i+1])`` of the series, vectorised with
    ``reduceat`` (a replay of a 5-minute log has hundreds of windows per signal); segments with a NaN fall
    back to :func:`fit_metrics`."""
    y = np.asarray(measured, dtype=float).ravel()
    m = np.asarray(model, dtype=float).ravel()
    starts = np.asarray(starts, dtype=int)
    if y.shape != m.shape:
        raise MetricsError(f"measured has {y.size} samples, model {m.size}: they must match")
    counts = np.diff(np.append(starts, y.size))
    if np.any(counts <= 0):
        raise MetricsError("segment starts must increase strictly and lie inside the series")
    finite = np.isfinite(y) & np.isfinite(m)
    e = np.where(finite, y - m, 0.0)
    yy, mm = np.where(finite, y, 0.0), np.where(finite, m, 0.0)
    sum_e2 = np.add.reduceat(e * e, starts)
    sum_y, sum_y2 = np.add.reduceat(yy, starts), np.add.reduceat(yy * yy, starts)
    sum_m2 = np.add.reduceat(mm * mm, starts)
    span = np.maximum.reduceat(yy, starts) - np.minimum.reduceat(yy, starts)
    max_err = np.maximum.reduceat(np.abs(e), starts)
    bad = np.add.reduceat(~finite, starts) > 0
    out = []
    for i, n in enumerate(counts):
        if bad[i]:
            a = starts[i]
            out.append(fit_metrics(y[a:a + n], m[a:a + n]))
            continue
        rmse = float(np.sqrt(sum_e2[i] / n))
        ss_tot = float(sum_y2[i] - sum_y[i] ** 2 / n)
        ss_tot = ss_tot if ss_tot > 1e-12 * max(float(sum_y2[i]), 1e-300) else 0.0
        den = float(np.sqrt(sum_y2[i] / n) + np.sqrt(sum_m2[i] / n))
        out.append(FitMetrics(
            rmse=rmse,
            nrmse=rmse / float(span[i]) if span[i] > 0 else float("inf"),
            theil_u=rmse / den if den > 0 else 0.0,
            fit_percent=100.0 * (1.0 - np.sqrt(sum_e2[i] / ss_tot)) if ss_tot > 0 else float("-inf"),
            r2=1.0 - float(sum_e2[i]) / ss_tot if ss_tot > 0 else float("-inf"),
            max_error=float(max_err[i]),
            n=int(n),
        ))
    return out
