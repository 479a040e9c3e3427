"""Least squares with a coloured residual: the coefficient covariance of a regression pooled over windows whose
residual is one stationary, serially correlated process (Newey-West with the autocovariance pooled over the
windows). Beside the output-error estimator's coloured bounds (:mod:`identification.estimation.oem`), whose lag
window rule it shares."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from identification.estimation.oem import correlation_lags


def hac_least_squares(xs: Sequence[np.ndarray], ys: Sequence[np.ndarray], min_lags: int = 0
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Least squares ``y = X beta`` pooled over contiguous windows (``xs`` N x p and ``ys`` N per window, windows
    independent of each other): ``beta`` and its covariance for a coloured residual (Newey & West 1987, with the
    residual's autocovariance pooled over the windows). The sensors' noise is one stationary process in every
    window, so its autocovariance ``R(k)`` is estimated from all of them, tapered by a Bartlett window at the lag
    where it dies out, at least ``min_lags`` (a moving average of n samples correlates the residual over n lags:
    a taper of 4 n keeps 92 % of that correlation's sum, the 2 n the autocorrelation test finds only 83 %).
    The score's variance is then ``sum_windows sum_ij x_i R(j - i) x_j``: right when one window carries most of
    a regressor's variation, where a bootstrap over windows is far too wide and a per-window Newey-West sum,
    from that window's few independent stretches, too narrow."""
    xtx = sum(x.T @ x for x in xs)
    xty = sum(x.T @ y for x, y in zip(xs, ys, strict=True))
    beta = np.linalg.lstsq(xtx, xty, rcond=None)[0]
    rs = [y - x @ beta for x, y in zip(xs, ys, strict=True)]
    n_total = sum(len(r) for r in rs)
    longest = max(len(r) for r in rs)
    lags = min(max(max(correlation_lags(r[:, None]) for r in rs if len(r) >= 2), min_lags), longest // 2)
    acov = np.zeros(lags + 1)
    for r in rs:
        m = min(lags + 1, len(r))
        acov[:m] += [float(r[:len(r) - k] @ r[k:]) for k in range(m)]
    acov *= (1.0 - np.arange(lags + 1) / (lags + 1.0)) / n_total
    middle = np.zeros_like(xtx)
    for x in xs:
        middle += acov[0] * (x.T @ x)
        for k in range(1, min(lags + 1, len(x))):
            c = x[:-k].T @ x[k:]
            middle += acov[k] * (c + c.T)
    inv = np.linalg.pinv(xtx)
    return beta, inv @ middle @ inv


__all__ = ["hac_least_squares"]
