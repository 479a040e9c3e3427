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
