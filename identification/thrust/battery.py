"""Battery state of a flight that logs no voltage: a thrust scale estimated from the hover condition.

A battery sags during a flight and differs between flights, so the thrust a command gives drifts (on the
Erle quadrotor of ../shared/data the hover PWM differs by 4 % between flights for the same weight). With
no voltage logged, the flight's own log still says how much thrust the vehicle needed: while it hovers
(|climb rate| below a threshold; every airborne sample when no climb rate is logged, since over many
seconds the mean vertical acceleration is ~0) the rotors carry the weight ``m g``. The estimate is the
causal, exponentially forgetting ratio

    s(t) = sum_k a_k m g / sum_k a_k T_model(k) cos(roll_k) cos(pitch_k),   a_k = exp(-(t - t_k) / tau),
    over hover samples t_k <= t (a tilted rotor disc carries the weight with its vertical part only),

so ``s`` follows a battery state with time constant ``tau`` (chosen by nested cross-validation on the
training flights) and needs no accelerometer: mass, PWM and climb rate only. This is the same signal an
autopilot's hover-throttle learning tracks (ArduCopter ``MOT_THST_HOVER``), so a HIL bench can compute it
online. A recursive estimator knows nothing at first, so up to ``tau`` after the first hover sample the
estimate is the batch ratio over that first window (the only look-ahead: at most ``tau`` seconds at the
start of a log); a flight with no hover sample keeps ``s = 1``.

The FMU receives it through its ``battery_voltage_V`` input as an equivalent voltage ``V_nom s``: a map
identified without voltage has ``thrust_voltage_exponent = 1``, so its thrust scales as ``V / V_nom``.
"""

from __future__ import annotations

import math

import numpy as np

#: hover when |climb rate| is below this [m/s] (calibration, battery state, summaries; replays read it back)
HOVER_CLIMB_M_S = 0.3
#: candidate time constants of the hover-condition estimate [s]; nested CV picks one (or none)
HOVER_TAUS_S = (10.0, 30.0, 120.0)


def hover_thrust_scale(time_s: np.ndarray, model_N: np.ndarray, hover: np.ndarray, weight_N: float,
                       tau_s: float) -> np.ndarray:
    """Causal thrust-scale estimate ``s(t)`` (see the module docstring); ``model_N`` is the vertical part of
    the model's total thrust without the state [N], ``hover`` the samples where the rotors carry the weight."""
    if not (math.isfinite(tau_s) and tau_s > 0.0):
        raise ValueError(f"tau_s = {tau_s}; allowed a finite time constant > 0 s")
    t = np.asarray(time_s, float)
    pred = np.asarray(model_N, float)
    h = np.asarray(hover, bool) & np.isfinite(pred) & (pred > 0.0)
    decay = np.exp(-np.maximum(np.diff(t, prepend=t[:1]), 0.0) / tau_s)
    out = np.ones(t.size)
    num = den = 0.0
    for k in range(t.size):  # a few thousand samples: a plain loop is a few ms
        num *= decay[k]
        den *= decay[k]
        if h[k]:
            num += weight_N
            den += pred[k]
        if den > 0.0:
            out[k] = num / den
    idx = np.flatnonzero(h)
    if idx.size:
        start = t <= t[idx[0]] + tau_s
        first = idx[start[idx]]
        out[start] = weight_N * first.size / float(pred[first].sum())
    return out


def equivalent_voltage_V(scale: np.ndarray, nominal_V: float) -> np.ndarray:
    """The ``battery_voltage_V`` input [V] that makes a no-voltage map (exponent 1) scale its thrust by ``scale``."""
    return nominal_V * np.asarray(scale, float)
