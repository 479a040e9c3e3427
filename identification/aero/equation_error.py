"""Equation-error estimate of the fixed-wing derivatives: smoothed states, then stepwise regression of the
measured force and moment coefficients on states and inputs (Klein & Morelli 2006, ch. 5 and sec. 5.4;
SIDPAC's ``lesq``/``swr``).

Per segment the signals are resampled on the fit grid; airspeed and GPS velocity (slow, coarse) are smoothed
(Savitzky-Golay, 0.1 s). The angular accelerations are the rate increments over each step and the states
their step midpoints, the inputs held over the step (the trapezoidal rule: a smoothed central-difference
derivative of a 50 Hz log underestimated every roll derivative of the Aerosonde, roll mode time constant
~0.05 s, by 35-45 %; this form is within 11 % on that noise-free synthetic flight,
tests/identification/aero/test_aero_ee.py).
The Euler equations with the airframe's inertia turn them into the moment coefficients; the side-force
coefficient is ``m a_y / (q S)`` from the accelerometer. Angle of attack and sideslip come from the GPS
velocity rotated into body axes with the logged attitude (no wind assumed: a note says so; without GPS
velocity the sideslip terms are left out).
For each coefficient the candidate regressors enter by their partial F statistic (F > 4) and leave when it
drops below (stepwise, Efroymson), an intercept always in; standard errors are the ordinary least-squares
ones, which coloured equation errors make optimistic (the output-error bounds are the ones to quote).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
from scipy.signal import savgol_filter

from fmu_models.common.rigid_body import body_moments_N_m, inertia_matrix
from identification.aero import model as aero
from identification.estimation.oem import Estimate

#: partial F statistic to enter and to stay in the model (SIDPAC's default F_in = F_out = 4)
F_IN = 4.0
#: Savitzky-Golay smoothing window [s] for states and their derivatives
SMOOTH_S = 0.1
#: regressors (name -> model derivative) of each coefficient
CANDIDATES = {
    "C_ell": {"beta": "C_ell_beta", "p_hat": "C_ell_p", "r_hat": "C_ell_r", "da": "C_ell_delta_a",
              "dr": "C_ell_delta_r"},
    "C_n": {"beta": "C_n_beta", "p_hat": "C_n_p", "r_hat": "C_n_r", "da": "C_n_delta_a", "dr": "C_n_delta_r"},
    "C_Y": {"beta": "C_Y_beta", "p_hat": "C_Y_p", "r_hat": "C_Y_r", "da": "C_Y_delta_a", "dr": "C_Y_delta_r"},
    "C_m": {"alpha": "C_m_alpha", "q_hat": "C_m_q", "de": "C_m_delta_e"},
}


class EquationErrorError(ValueError):
    """Too few samples, or signals the regression needs are missing."""


@dataclass
class EquationErrorResult:
    """Derivatives by equation error: value, OLS std, which terms entered, fit R^2 per coefficient."""

    values: dict[str, float]
    std: dict[str, float]
    r_squared: dict[str, float]
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return {"method": "equation error, stepwise regression (F_in = F_out = 4), OLS std",
                "values": self.values, "std": self.std, "r_squared": self.r_squared, "notes": self.notes}

    def beside(self, est: Estimate) -> list[str]:
        """The rival beside the output-error estimate, for the derivatives both have."""
        oe = est.derivatives()
        rows = ["equation error (rival, start) beside output error:",
                f"  {'parameter':<16} {'equation error':>16} {'(OLS std)':>10} {'output error':>13}"]
        for n, v in self.values.items():
            if n in oe:
                rows.append(f"  {n:<16} {v:16.5g} {self.std[n]:10.3g} {oe[n]:13.5g}")
        rows += [f"  note: {x}" for x in self.notes]
        return rows


def _smooth(x: np.ndarray, rate_hz: float, deriv: int = 0) -> np.ndarray:
    n = max(5, int(SMOOTH_S * rate_hz) | 1)
    n = min(n, len(x) - (1 - len(x) % 2))
    return savgol_filter(x, n, 2, deriv=deriv, delta=1.0 / rate_hz, axis=0)


def _mid(x: np.ndarray) -> np.ndarray:
    """Means of consecutive samples: the states at the middle of each step."""
    return 0.5 * (x[1:] + x[:-1])


def _segment_rows(model: Any, pv: dict[str, float], log: Any, mapping: Any, seg: aero.Segment,
                  rate_hz: float) -> dict[str, np.ndarray] | None:
    t = aero.grid(seg, rate_hz)
    if len(t) < 20:
        return None
    sig = {n: log.signal(n).resample(t) for n in ("gyro_body_x_rad_s", "gyro_body_y_rad_s", "gyro_body_z_rad_s",
                                                  "roll_rad", "pitch_rad", "airspeed_m_s", "accel_body_y_m_s2")}
    w = np.column_stack([sig[f"gyro_body_{a}_rad_s"] for a in "xyz"])
    p, q, r = _mid(w).T
    # trapezoidal: exact to O(dt^3) for the fast roll mode
    moment = body_moments_N_m(np.asarray(ca.DM(inertia_matrix(pv["Jx_kg_m2"], pv["Jy_kg_m2"], pv["Jz_kg_m2"],
                                                             pv["Jxz_kg_m2"]))), _mid(w), np.diff(w, axis=0) * rate_hz)
    va = np.maximum(_mid(_smooth(sig["airspeed_m_s"], rate_hz)), 3.0)
    qs = 0.5 * pv["rho_kg_m3"] * va ** 2 * pv["S_wing_m2"]
    b, c = pv["b_m"], pv["c_m"]
    u = aero.log_inputs(model, log, mapping, t)[:-1]  # zero-order hold over each step
    names = list(model.inputs.index)
    rows = {
        "C_ell": moment[:, 0] / (qs * b), "C_m": moment[:, 1] / (qs * c), "C_n": moment[:, 2] / (qs * b),
        "C_Y": pv["mass_kg"] * _mid(sig["accel_body_y_m_s2"]) / qs,
        "p_hat": p * b / (2 * va), "q_hat": q * c / (2 * va), "r_hat": r * b / (2 * va),
        "da": u[:, names.index("aileron_rad")], "de": u[:, names.index("elevator_rad")],
        "dr": u[:, names.index("rudder_rad")],
    }
    if all(log.has(f"vel_{a}_m_s") for a in ("north", "east", "down")):
        from identification.logs.log_state import _euler_dcm, resample_angle

        yaw = resample_angle(log.signal("yaw_rad"), t)
        v_ned = np.column_stack([_smooth(log.signal(f"vel_{a}_m_s").resample(t), rate_hz)
                                 for a in ("north", "east", "down")])
        vb = np.array([_euler_dcm(sig["roll_rad"][k], sig["pitch_rad"][k], yaw[k]).T @ v_ned[k]
                       for k in range(len(t))])
        rows["alpha"] = _mid(np.arctan2(vb[:, 2], vb[:, 0]))
        rows["beta"] = _mid(np.arcsin(np.clip(vb[:, 1] / np.maximum(np.linalg.norm(vb, axis=1), 1.0), -1, 1)))
    return rows


def stepwise(y: np.ndarray, X: dict[str, np.ndarray], f_in: float = F_IN, max_steps: int = 50
             ) -> tuple[list[str], np.ndarray, np.ndarray, float]:
    """Forward-backward stepwise regression with an intercept: terms enter when their partial F exceeds
    ``f_in`` and leave when it falls below; returns (terms, coefficients, OLS std, R^2) without the intercept."""
    names = list(X)
    chosen: list[str] = []
    n = len(y)

    def fit(terms: list[str]) -> tuple[np.ndarray, np.ndarray, float]:
        A = np.column_stack([np.ones(n), *[X[t] for t in terms]])
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        res = y - A @ coef
        s2 = float(res @ res) / max(n - A.shape[1], 1)
        cov = s2 * np.linalg.pinv(A.T @ A)
        return coef, np.sqrt(np.maximum(np.diag(cov), 0.0)), float(res @ res)

    for _ in range(max_steps):
        _, _, sse = fit(chosen)
        best, best_f = None, f_in
        for t in (t for t in names if t not in chosen):
            _, _, sse_t = fit([*chosen, t])
            f = (sse - sse_t) / max(sse_t / max(n - len(chosen) - 2, 1), 1e-300)
            if f > best_f:
                best, best_f = t, f
        if best is None:
            break
        chosen.append(best)
        coef, std, _ = fit(chosen)
        chosen = [t for i, t in enumerate(chosen) if (coef[i + 1] / max(std[i + 1], 1e-300)) ** 2 >= f_in]
    coef, std, sse = fit(chosen)
    sst = float(np.sum((y - y.mean()) ** 2))
    return chosen, coef[1:], std[1:], 1.0 - sse / sst if sst > 0 else float("nan")


def equation_error(model: Any, p: np.ndarray, sources: Sequence[Any], items: Sequence[tuple[int, aero.Segment]],
                   rate_hz: float) -> EquationErrorResult:
    """Equation-error estimate over the fit segments of every log (``sources``: ``AeroSource`` list)."""
    pv = dict(zip(model.params.index, p, strict=True))
    parts = [_segment_rows(model, pv, sources[k].log, sources[k].mapping, seg, rate_hz) for k, seg in items]
    parts = [x for x in parts if x is not None]
    if not parts:
        raise EquationErrorError("no segment long enough for the equation-error regression")
    keys = set.intersection(*(set(x) for x in parts))
    data = {k: np.concatenate([x[k] for x in parts]) for k in keys}
    values, std, r2, notes = {}, {}, {}, []
    if "beta" not in data:
        notes.append("no GPS velocity in a log: angle of attack and sideslip terms left out")
    else:
        notes.append("angle of attack and sideslip from GPS velocity in body axes, no wind assumed")
    for coef, cands in CANDIDATES.items():
        X = {k: data[k] for k in cands if k in data}
        terms, c, s, r2[coef] = stepwise(data[coef], X)
        for t, v, e in zip(terms, c, s, strict=True):
            values[cands[t]], std[cands[t]] = float(v), float(e)
        left = [cands[k] for k in X if k not in terms]
        if left:
            notes.append(f"{coef}: {', '.join(left)} did not enter (partial F < {F_IN:g})")
    return EquationErrorResult(values, std, r2, notes)
