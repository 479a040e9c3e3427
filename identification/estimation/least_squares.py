"""Least squares with a coloured residual: the coefficient covariance of a regression pooled over windows whose
residual is one stationary, serially correlated process (Newey-West with the autocovariance pooled over the
windows). Beside the output-error estimator's coloured bounds (:mod:`identification.estimation.oem`), whose lag
window rule it shares."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from identification.estimation.oem import correlation_lags


def hac_least_squares(xs: Sequence[np.ndarray], ys: Sequence[np.ndarray], min_lags: int = 0,
                      groups: Sequence[int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Least squares ``y = X beta`` pooled over contiguous windows (``xs`` N x p and ``ys`` N per window, windows
    independent of each other): ``beta`` and its covariance for a coloured residual (Newey & West 1987, with the
    residual's autocovariance pooled over the windows). The sensors' noise is one stationary process in every
    window, so its autocovariance ``R(k)`` is estimated from all of them, kept whole up to the lag where it dies
    out (at least ``min_lags``: a moving average of n samples correlates the residual over n lags) and tapered
    linearly to zero over as many lags again (the flat-top window of Politis & Romano 1995). A Bartlett taper
    from lag 0 would scale down the correlation it is meant to keep: over 4 n lags it keeps 92 % of a moving
    average's correlation sum, a variance 8 % short and 95 % intervals that cover about 93 %. Pooled over many
    windows the far lags are well estimated, so the flat top costs little noise; should its covariance come out
    not positive definite, the Bartlett window over the same span is used.
    ``groups`` (one label per window, default one per window) names the windows whose samples the caller
    centred together (one constant per log): a residual centred over ``N`` samples has its autocovariance
    lowered at every lag by about its long-run variance over ``N``, which summed over a window of ``W`` lags
    takes ``W g / n`` of the variance (``g`` groups, ``n`` samples: 16 % for 8 windows of 3000 samples centred
    one by one and a 480-lag window), so each lag gets that back (the long-run variance solved for with it).
    The score's variance is then ``sum_windows sum_ij x_i R(j - i) x_j``: right when one window carries most of
    a regressor's variation, where a bootstrap over windows is far too wide and a per-window Newey-West sum,
    from that window's few independent stretches, too narrow."""
    xtx = sum(x.T @ x for x in xs)
    xty = sum(x.T @ y for x, y in zip(xs, ys, strict=True))
    beta = np.linalg.lstsq(xtx, xty, rcond=None)[0]
    rs = [y - x @ beta for x, y in zip(xs, ys, strict=True)]
    n_total = sum(len(r) for r in rs)
    longest = max(len(r) for r in rs)
    flat = min(max(max(correlation_lags(r[:, None]) for r in rs if len(r) >= 2), min_lags), longest // 2)
    span = min(2 * flat, longest - 1)
    acov = np.zeros(span + 1)
    for r in rs:
        m = min(span + 1, len(r))
        acov[:m] += _lagged(r[:, None], m)[:, 0, 0]
    acov /= n_total
    k = np.arange(span + 1)
    n_groups = len(xs) if groups is None else len(set(groups))
    inv = np.linalg.pinv(xtx)
    cov = np.zeros_like(xtx)
    for weights in (np.clip((2.0 * flat - k) / max(flat, 1), 0.0, 1.0), 1.0 - k / (span + 1.0)):
        lost = n_groups * (2.0 * weights.sum() - weights[0]) / n_total  # share of the long-run variance
        long_run = (2.0 * float(weights @ acov) - weights[0] * acov[0]) / max(1.0 - lost, 0.5)
        cov = inv @ _middle(xs, weights * (acov + long_run * n_groups / n_total)) @ inv
        if np.all(np.linalg.eigvalsh(0.5 * (cov + cov.T)) >= 0.0):
            break
    return beta, cov


def _middle(xs: Sequence[np.ndarray], acov: np.ndarray) -> np.ndarray:
    """``sum_windows sum_ij x_i R(j - i) x_j`` for the (tapered) autocovariance ``acov`` at lags 0..len-1."""
    p = xs[0].shape[1]
    middle = np.zeros((p, p))
    for x in xs:
        m = min(len(acov), len(x))
        c = np.tensordot(acov[1:m], _lagged(x, m)[1:], axes=1)  # sum_k R(k) x[:-k]' x[k:]
        middle += acov[0] * (x.T @ x) + c + c.T
    return middle


def _lagged(x: np.ndarray, lags: int) -> np.ndarray:
    """``out[k] = x[:-k]' x[k:]`` (p x p) for the columns of ``x`` (N x p), lags k = 0..``lags``-1, by FFT: one
    transform per column instead of a product per lag (the drag regression's windows take hundreds of lags).
    Zero-padded to at least N + lags samples, so no lag wraps around."""
    n = len(x)
    size = 1 << int(n + lags - 1).bit_length()
    f = np.fft.rfft(x, size, axis=0)
    cross = np.fft.irfft(np.conj(f)[:, :, None] * f[:, None, :], size, axis=0)[:lags]
    return np.asarray(cross)


__all__ = ["hac_least_squares"]
