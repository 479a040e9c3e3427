"""Small-perturbation linear model of the fixed wing at a trim, and its classical modes.

The Jacobians are exact derivatives (CasADi) of the same ``derivatives`` function the FMU compiles, taken in
the reduced state ``[u, v, w, phi, theta, p, q, r]`` (body velocities, roll and pitch angle, body rates):
heading and position are neutral and drop out. Attitude enters the full model through the quaternion of the
3-2-1 Euler angles; the Euler-angle rates are the kinematic relations (Beard & McLain eq. 3.3)
``phi' = p + tan(theta) (q sin(phi) + r cos(phi))``, ``theta' = q cos(phi) - r sin(phi)``.

Modes (Beard & McLain ch. 5; Etkin & Reid ch. 6): at wings-level trim the motion splits into the
longitudinal set ``[u, w, q, theta]`` and the lateral set ``[v, p, r, phi]``. Each set's eigenvalues are
classified: longitudinal = short period (the pair of largest magnitude) and phugoid (the other pair);
lateral = roll subsidence (the fastest real root), spiral (the slowest real root) and Dutch roll (the
remaining pair). A "pair" is described by ``wn = sqrt(l1 l2)`` and ``zeta = -(l1 + l2) / (2 wn)``, which for a
complex pair are its natural frequency and damping ratio, and stay meaningful for an overdamped pair.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from fmu_models.common.model import derivative_function
from fmu_models.common.rigid_body import quat_from_euler
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import Trim

#: names of the reduced state, in order
STATES = ("u_m_s", "v_m_s", "w_m_s", "roll_rad", "pitch_rad", "p_rad_s", "q_rad_s", "r_rad_s")
#: the inputs, in the model's order
INPUTS = ("aileron_rad", "elevator_rad", "rudder_rad", "throttle")
LONGITUDINAL = (0, 2, 6, 4)  #: u, w, q, theta
LATERAL = (1, 5, 7, 3)  #: v, p, r, phi


@dataclass(frozen=True)
class Mode:
    """One mode: eigenvalue(s) [1/s], natural frequency [rad/s], damping ratio, time constant [s] (real root)."""

    name: str
    eigenvalues: tuple[complex, ...]
    wn_rad_s: float
    zeta: float
    time_constant_s: float | None = None

    @property
    def stable(self) -> bool:
        return all(e.real < 0 for e in self.eigenvalues)

    def as_dict(self) -> dict[str, object]:
        return {"name": self.name, "eigenvalues": [[e.real, e.imag] for e in self.eigenvalues],
                "wn_rad_s": self.wn_rad_s, "zeta": self.zeta, "time_constant_s": self.time_constant_s,
                "stable": self.stable}


@dataclass(frozen=True)
class LinearModel:
    """``dx/dt = A dx + B du`` about the trim, in :data:`STATES` and :data:`INPUTS`."""

    A: np.ndarray
    B: np.ndarray
    x_trim: np.ndarray
    u_trim: np.ndarray
    va_m_s: float

    def sub(self, idx: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """``(A, B)`` restricted to the states ``idx``."""
        i = list(idx)
        return self.A[np.ix_(i, i)], self.B[i, :]


def _reduced_dynamics(model: FixedWingModel, trim: Trim) -> ca.Function:
    """``g(xr, u, p) -> xr_dot`` of the reduced state, through the full model's derivatives."""
    f = derivative_function(model)
    xr, u, p = ca.SX.sym("xr", 8), ca.SX.sym("u", 4), ca.SX.sym("p", len(model.params))
    phi, theta = xr[3], xr[4]
    x = ca.vertcat(ca.DM(trim.x[0:3]), xr[0:3], quat_from_euler(phi, theta, 0.0), xr[5:8], ca.DM(trim.x[13:16]))
    xd = f(x, u, p)
    pr, qr, rr = xr[5], xr[6], xr[7]
    phid = pr + ca.tan(theta) * (qr * ca.sin(phi) + rr * ca.cos(phi))
    thetad = qr * ca.cos(phi) - rr * ca.sin(phi)
    rhs = ca.vertcat(xd[3:6], phid, thetad, xd[10:13])
    return ca.Function("reduced", [xr, u, p], [rhs, ca.jacobian(rhs, xr), ca.jacobian(rhs, u)])


def linearise(model: FixedWingModel, p: np.ndarray, trim: Trim) -> LinearModel:
    """Exact Jacobians of the fixed-wing model at ``trim`` (a wings-level trim from :func:`trim.trim`)."""
    g = _reduced_dynamics(model, trim)
    q = trim.x[6:10]
    theta = math.asin(max(-1.0, min(1.0, 2.0 * (q[0] * q[2] - q[3] * q[1]))))
    xr = np.array([*trim.x[3:6], 0.0, theta, *trim.x[10:13]])
    rhs, A, B = g(xr, trim.u, p)
    residual = float(np.linalg.norm(np.asarray(rhs)))
    if not math.isfinite(residual):
        raise ValueError("the linearisation is not finite at this trim")
    va = float(np.linalg.norm(trim.x[3:6]))
    return LinearModel(np.asarray(A, dtype=float), np.asarray(B, dtype=float), xr, np.asarray(trim.u, float), va)


def _pair(name: str, ev: list[complex]) -> Mode:
    prod = (ev[0] * ev[1]).real
    wn = math.sqrt(abs(prod))
    zeta = -(ev[0] + ev[1]).real / (2 * wn) if wn > 0 else 1.0
    return Mode(name, tuple(ev), wn, zeta)


def _real(name: str, e: complex) -> Mode:
    lam = e.real
    return Mode(name, (e,), abs(lam), 1.0 if lam < 0 else -1.0, 1.0 / abs(lam) if lam != 0 else math.inf)


def longitudinal_modes(lin: LinearModel) -> tuple[Mode, Mode]:
    """``(short period, phugoid)``: the eigenvalue pair of largest magnitude, and the other pair."""
    A, _ = lin.sub(LONGITUDINAL)
    ev = sorted(np.linalg.eigvals(A), key=abs)
    return _pair("short_period", ev[2:]), _pair("phugoid", ev[:2])


def lateral_modes(lin: LinearModel) -> tuple[Mode, Mode, Mode]:
    """``(roll subsidence, Dutch roll, spiral)`` of the lateral set."""
    A, _ = lin.sub(LATERAL)
    ev = list(np.linalg.eigvals(A))
    cplx = [e for e in ev if abs(e.imag) > 1e-9 * max(1.0, abs(e))]
    real = sorted((e for e in ev if e not in cplx), key=abs)
    if len(cplx) == 2:
        dutch = cplx
    else:  # all real (an overdamped Dutch roll): fastest = roll, slowest = spiral, the middle two = Dutch roll
        dutch, real = real[1:3], [real[0], real[3]]
    return _real("roll_subsidence", real[-1]), _pair("dutch_roll", dutch), _real("spiral", real[0])


@dataclass(frozen=True)
class Modes:
    """The five classical modes of a trim."""

    short_period: Mode
    phugoid: Mode
    roll_subsidence: Mode
    dutch_roll: Mode
    spiral: Mode

    def all(self) -> tuple[Mode, ...]:
        return (self.short_period, self.phugoid, self.roll_subsidence, self.dutch_roll, self.spiral)


def modes(lin: LinearModel) -> Modes:
    """Classify the eigenvalues of ``lin`` into the classical modes."""
    sp, ph = longitudinal_modes(lin)
    roll, dr, sp_ = lateral_modes(lin)
    return Modes(sp, ph, roll, dr, sp_)


# --------------------------------------------------------------------------- one-axis approximations
@dataclass(frozen=True)
class RateAxis:
    """One rate axis, linear, decoupled: ``x' = A x + b surface`` [rad/s per rad]; the rate is state
    ``rate_index`` (roll ``[p]``, pitch ``[alpha, q]``, yaw ``[beta, r]``)."""

    a: np.ndarray
    b: np.ndarray
    rate_index: int


def rate_axes(pv: Any, va_m_s: float) -> dict[str, RateAxis]:
    """Roll subsidence ``[p]``, short period ``[alpha, q]`` and Dutch roll ``[beta, r]`` at airspeed ``va_m_s``
    [m/s] from the dimensional derivatives (Beard & McLain ch. 5 with the Gamma inertia terms: roll
    ``p' = -a_phi1 p + a_phi2 da`` with ``a_phi1 = -q S b C_p_p b / (2 V)``, ``a_phi2 = q S b C_p_da``;
    ``M_q = q S c C_m_q c / (2 V Jy)``, ``M_a = q S c C_m_a / Jy``, ``M_de = q S c C_m_de / Jy``, ``C_r_*`` for
    yaw; ``q = rho V^2 / 2``). ``pv``
    is a parameter view (attribute access, e.g. ``FixedWingParams``); density ``rho_kg_m3``. The exact
    coupled linearisation is :func:`linearise`; these are what a rate-loop design uses."""
    qbar = 0.5 * pv.rho_kg_m3 * va_m_s ** 2
    gam = pv.Jx_kg_m2 * pv.Jz_kg_m2 - pv.Jxz_kg_m2 ** 2
    g3, g4, g8 = pv.Jz_kg_m2 / gam, pv.Jxz_kg_m2 / gam, pv.Jx_kg_m2 / gam
    b, c, s, m = pv.b_m, pv.c_m, pv.S_wing_m2, pv.mass_kg
    k_lat = qbar * s * b
    roll = RateAxis(np.array([[k_lat * (g3 * pv.C_ell_p + g4 * pv.C_n_p) * b / (2 * va_m_s)]]),
                    np.array([k_lat * (g3 * pv.C_ell_delta_a + g4 * pv.C_n_delta_a)]), 0)
    k_lon = qbar * s * c / pv.Jy_kg_m2
    z_a = -qbar * s * pv.C_L_alpha / (m * va_m_s)
    pitch = RateAxis(np.array([[z_a, 1.0], [k_lon * pv.C_m_alpha, k_lon * pv.C_m_q * c / (2 * va_m_s)]]),
                     np.array([0.0, k_lon * pv.C_m_delta_e]), 1)
    c_rb = g4 * pv.C_ell_beta + g8 * pv.C_n_beta
    c_rr = g4 * pv.C_ell_r + g8 * pv.C_n_r
    y_b = qbar * s * pv.C_Y_beta / (m * va_m_s)
    yaw = RateAxis(np.array([[y_b, -1.0], [k_lat * c_rb, k_lat * c_rr * b / (2 * va_m_s)]]),
                   np.array([0.0, k_lat * (g4 * pv.C_ell_delta_r + g8 * pv.C_n_delta_r)]), 1)
    return {"roll": roll, "pitch": pitch, "yaw": yaw}
