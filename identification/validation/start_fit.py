"""A fixed-wing replay window's start velocity, read from the accelerometer instead of the GPS alone.

A replay restarts each window from the logged state (``identification.logs.log_state.initial_values_at``): the
attitude and body rates as logged, the body velocity from the GPS velocity rotated into the body. For a fixed wing
the GPS velocity is the weak part of that state: at 5 Hz, interpolated, lagging the vehicle (ArduPilot SITL's
default GPS lag is 100 ms) and noisy, it puts the start's sideslip and angle of attack off by a degree or more in a
manoeuvre, and the model's answer to that false start (a lateral and vertical force, then a yaw and pitch rate
transient) fills the first few tenths of a second of every window. Measured on the shared ArduPlane excitation log
(``docs/validation.md``, its three held-out segments): the replay's specific force z was 0.59 m/s^2 off in the
first 0.1 s of the windows against 0.06-0.10 m/s^2 after 1 s.

The accelerometer reads that start directly: its lateral and vertical specific force are, for a fixed wing, set
by the sideslip and the angle of attack. So each window's body velocity ``v, w`` is taken as the one for which the
FMU's ``accel_body_y_m_s2`` and ``accel_body_z_m_s2`` at the restart equal the log's there (interpolated at the
restart, as the attitude and rates are; no later sample, none that is scored): a 2 x 2 Newton solve on the FMU
itself (forward-difference sensitivities, a few initialisations per window; the forward speed stays the GPS's).
Not a mean over the samples before the restart: in a manoeuvre the force moves within a tenth of a second, and
that lag cost more than the accelerometer's noise (on the shared ArduPlane log a 0.1 s mean left the replay's yaw
error 3 times the one the restart's own sample gives; on a synthetic flight its start errors were outside the noise
the Monte Carlo draws them with). A start whose solve fails, or would move ``v`` or ``w`` more than
``START_FORCE_MAX_CHANGE_M_S`` from the GPS's (a force the model cannot make with a plausible sideslip or angle of
attack), keeps the logged velocity and is counted in the replay's notes. ``validate --start-velocity logged`` keeps
the GPS's throughout.

The one-step force check of the replay stays on the logged start (it tests the force model at the logged state;
at the fitted start its y and z would be zero by construction). The Monte Carlo's restart-state noise of ``v`` and
``w`` is then the accelerometer's (its white noise, through the solve's sensitivities), not the GPS's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from fmu_models.fmi.host import FmuHost, FmuRunError
from identification.logs.flightlog import FlightLog
from identification.logs.log_state import interpolation_variance_factor, noise_std

#: the unknowns (FMU start parameters) and the outputs they are solved to match, in that order
UNKNOWNS = ("init_vel_body_y_m_s", "init_vel_body_z_m_s")
TARGETS = ("accel_body_y_m_s2", "accel_body_z_m_s2")
#: a solve that would move v or w more than this [m/s] from the GPS's keeps the GPS's (about 7 degrees of sideslip
#: or angle of attack at 25 m/s: beyond the GPS's error, a force the model cannot make plausibly)
START_FORCE_MAX_CHANGE_M_S = 3.0
#: Newton iterations and the forward-difference step [m/s] of the sensitivities; the solve stops once the force
#: matches within ``START_FORCE_TOL_M_S2``
START_FORCE_ITERATIONS = 4
START_FORCE_STEP_M_S = 0.01
START_FORCE_TOL_M_S2 = 1e-4


@dataclass
class StartFit:
    """What :func:`force_consistent_starts` did: the starts (fitted where it could); the FMU's ``extra`` outputs at
    each logged start (the one-step check's; NaN for windows not scored or where the FMU failed there); how many
    starts were fitted and why the others kept the logged velocity; the fitted unknowns' restart noise std [m/s]."""

    starts: list[dict[str, float]]
    logged_first: np.ndarray
    fitted: int = 0
    kept: dict[str, int] = field(default_factory=dict)
    start_std: dict[str, float] = field(default_factory=dict)

    def note(self) -> str | None:
        """A line for the replay's notes when a start kept the logged velocity, else None."""
        if not self.kept:
            return None
        why = "; ".join(f"{reason}: {count}" for reason, count in self.kept.items())
        return (f"start velocity: {sum(self.kept.values())} of {sum(self.kept.values()) + self.fitted} window "
                f"starts kept the GPS's body velocity instead of the one matching the logged specific force ({why})")


def applies(host: FmuHost, log: FlightLog, vehicle: str) -> bool:
    """Whether the fit can run: a fixed wing whose FMU takes the unknowns and gives the targets, and a log with
    the targets."""
    return (vehicle == "fixed_wing" and all(n in host.variables for n in (*UNKNOWNS, *TARGETS))
            and all(log.has(n) for n in TARGETS))


def logged_force(log: FlightLog, t0_s: float) -> np.ndarray:
    """The targets as logged at the restart ``t0_s`` [s] (linear between the samples around it)."""
    return np.array([float(log.signal(n).resample(np.array([t0_s]))[0]) for n in TARGETS])


def force_consistent_starts(host: FmuHost, log: FlightLog, t: np.ndarray, inputs: Mapping[str, np.ndarray],
                            edges: Sequence[int], included: Sequence[bool], starts: Sequence[Mapping[str, float]],
                            extra: Sequence[str]) -> StartFit:
    """Each included window's start (grid index ``edges[i]`` of ``t`` [s], FMU ``inputs`` on the grid) with
    :data:`UNKNOWNS` solved so that the FMU's :data:`TARGETS` at the restart match :func:`logged_force`; see the
    module docstring. ``extra``: outputs read at each logged start for the one-step check."""
    fit = StartFit([dict(s) for s in starts], np.full((len(starts), len(extra)), np.nan))
    sens: list[np.ndarray] = []
    factors: list[float] = []
    for i, st in enumerate(starts):
        if not included[i]:
            continue
        a = edges[i]
        # the inputs of the sample before: an output at a grid time is the step's that ends there, made with the
        # inputs held over it (as the replay's own outputs are), so a logged force at a servo step is the old one's
        at = {k: float(v[max(a - 1, 0)]) for k, v in inputs.items()}
        target = logged_force(log, float(t[a]))
        x0 = np.array([float(st[n]) for n in UNKNOWNS])
        try:
            if extra:  # the one-step check's: the restart as the replay makes it, inputs of the sample itself
                fit.logged_first[i] = _force(host, {**st, **{k: float(v[a]) for k, v in inputs.items()}}, x0,
                                             extra)[len(TARGETS):]
            x, f, jac = _solve(host, {**st, **at}, x0, target)
        except (FmuRunError, np.linalg.LinAlgError):
            key = "no solution (the FMU failed, or its force does not depend on v, w)"
            fit.kept[key] = fit.kept.get(key, 0) + 1
            continue
        if not np.all(np.isfinite(x)) or np.max(np.abs(target - f)) > 100 * START_FORCE_TOL_M_S2:
            fit.kept["no convergence"] = fit.kept.get("no convergence", 0) + 1
            continue
        if np.max(np.abs(x - x0)) > START_FORCE_MAX_CHANGE_M_S:
            key = f"a change above {START_FORCE_MAX_CHANGE_M_S:g} m/s"
            fit.kept[key] = fit.kept.get(key, 0) + 1
            continue
        fit.starts[i].update(zip(UNKNOWNS, map(float, x), strict=True))
        fit.fitted += 1
        sens.append(np.linalg.inv(jac))
        factors.append(interpolation_variance_factor(log.signal(TARGETS[0]), float(t[a])))
    if sens:
        fit.start_std = _start_std(log, sens, factors)
    return fit


def _force(host: FmuHost, start: Mapping[str, float], x: np.ndarray, also: Sequence[str] = ()) -> np.ndarray:
    """The :data:`TARGETS` (then ``also``) the FMU gives at a restart from ``start`` with :data:`UNKNOWNS` ``x``."""
    host.start({**start, **dict(zip(UNKNOWNS, map(float, x), strict=True))})
    got = host.get([*TARGETS, *also])
    return np.array([got[n] for n in (*TARGETS, *also)])


def _solve(host: FmuHost, start: Mapping[str, float], x0: np.ndarray, target: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Newton from ``x0``: the unknowns, the targets they give and the last sensitivities (d target / d unknown)."""
    x, f = x0.copy(), _force(host, start, x0)
    jac = np.full((len(TARGETS), len(UNKNOWNS)), np.nan)
    for _ in range(START_FORCE_ITERATIONS):
        for j in range(len(UNKNOWNS)):  # first, so that a start already matching still gives its sensitivities
            step = np.zeros(len(UNKNOWNS))
            step[j] = START_FORCE_STEP_M_S
            jac[:, j] = (_force(host, start, x + step) - f) / START_FORCE_STEP_M_S
        if np.max(np.abs(target - f)) < START_FORCE_TOL_M_S2:
            break
        x = x + np.linalg.solve(jac, target - f)
        f = _force(host, start, x)
    return x, f, jac


def _start_std(log: FlightLog, inverse_jacobians: Sequence[np.ndarray], factors: Sequence[float]) -> dict[str, float]:
    """RMS over the fitted starts of each unknown's std [m/s] from the targets' white noise (``noise_std`` of the
    whole log, independent axes; times each start's interpolation variance factor), through its solve's inverse
    sensitivities."""
    sd = np.array([noise_std(log.signal(n), [(-math.inf, math.inf)]) for n in TARGETS])
    var = np.zeros(len(UNKNOWNS))
    for inv, k in zip(inverse_jacobians, factors, strict=True):
        var += (inv * inv) @ (sd * sd * k)
    return {u: float(math.sqrt(v / len(inverse_jacobians))) for u, v in zip(UNKNOWNS, var, strict=True)}
