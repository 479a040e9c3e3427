"""Motor commands between slow logged outputs, from ArduCopter's rate-controller outputs (DataFlash ``RATE``).

A log can record the motor outputs (``RCOU``) too slowly for the rate dynamics (the Erle flights: 10 Hz) and the
rate controller's outputs to the mixer (``RATE`` ``ROut``, ``POut``, ``YOut``, ``AOut``: roll, pitch, yaw in -1..1,
throttle 0..1) at the fast-loop rate (400 Hz with ``LOG_BITMASK`` ATTITUDE_FAST). Between the two lies the
mixer: each motor's output is its throttle plus its roll, pitch and yaw factors times those inputs, then
ArduCopter's thrust linearisation and limits. :func:`reconstruct` fits, per motor, the logged PWM on
``[1, ROut, POut, YOut, AOut]`` at the logged output times (least squares: the factors and the PWM scale come
out of the log, no frame table needed) and keeps the result only when it predicts held-out output samples
(every third one) better than holding the previous output sample, the command the slow log would otherwise
give, over the whole 90 % block-bootstrap interval of its skill, for every motor. The thrust linearisation
and saturation are not modelled: a log where they bend the relation shows it in that score and is refused.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from fmu_models.quadrotor.constants import N_MOTORS
from identification.common.metrics import skill_interval
from identification.logs.flightlog import FlightLog, Signal
from identification.logs.log_state import hold
from identification.logs.readers.dataflash import RATE_OUTPUTS

#: the mixer inputs the fit uses (canonical names of the DataFlash reader's RATE fields)
MIXER_INPUTS = RATE_OUTPUTS
#: every n-th logged output sample is held out to score the fit
HOLD_OUT_EVERY = 3
#: held-out samples per bootstrap block (consecutive held-out samples are serially correlated)
BLOCK_SAMPLES = 10
#: fewest fitted output samples per motor (5 coefficients)
MIN_SAMPLES = 30


@dataclass
class MixerFit:
    """Per motor: coefficients on ``[1, *MIXER_INPUTS]`` [us], held-out RMSE [us] of the fit and of holding the
    previous output sample, and the skill interval; ``usable`` when every motor wins."""

    source: str
    rate_hz: float  #: rate of the mixer inputs [Hz]
    output_hz: float  #: rate of the logged motor outputs [Hz]
    coef_us: np.ndarray  #: N_MOTORS x 5
    rmse_us: list[float] = field(default_factory=list)
    rmse_hold_us: list[float] = field(default_factory=list)
    skill: list[dict[str, float]] = field(default_factory=list)
    usable: bool = False
    reason: str = ""

    def summary(self) -> str:
        per = ", ".join(f"motor {k + 1} {s['skill']:+.2f} [{s['lo']:+.2f}, {s['hi']:+.2f}] (RMSE {r:.1f} us against "
                        f"{h:.1f} us)" for k, (s, r, h) in enumerate(zip(self.skill, self.rmse_us,
                                                                           self.rmse_hold_us, strict=True)))
        return (f"{self.source}: motor commands rebuilt at {self.rate_hz:.0f} Hz from the RATE mixer inputs, fitted "
                f"on the {self.output_hz:.0f} Hz outputs; held-out skill against holding the previous output: {per}")


def _rate(t: np.ndarray) -> float:
    d = np.diff(t)
    d = d[d > 0]
    return float(1.0 / np.median(d)) if d.size else 0.0


def reconstruct(log: FlightLog) -> MixerFit | None:
    """The per-motor fit of the logged motor PWM on the RATE mixer inputs, scored on held-out output samples;
    None when the log has no RATE mixer inputs or no motor outputs."""
    motors = [f"motor_{k}_pwm_us" for k in range(1, N_MOTORS + 1)]
    if not all(log.has(n) for n in (*MIXER_INPUTS, *motors)):
        return None
    t_in = log.signal(MIXER_INPUTS[0]).t_s
    t_out = log.signal(motors[0]).t_s
    fit = MixerFit(log.source, _rate(t_in), _rate(t_out), np.full((N_MOTORS, 1 + len(MIXER_INPUTS)), np.nan))
    inside = (t_out >= t_in[0]) & (t_out <= t_in[-1])
    t = t_out[inside]
    held = np.arange(len(t)) % HOLD_OUT_EVERY == HOLD_OUT_EVERY - 1
    if (~held).sum() < MIN_SAMPLES or held.sum() < 2 * BLOCK_SAMPLES:
        fit.reason = (f"{len(t)} motor output samples during the RATE record: too few to fit and score "
                      f"(at least {MIN_SAMPLES} fitted and {2 * BLOCK_SAMPLES} held out)")
        return fit
    x = np.column_stack([np.ones(len(t)), *(hold(log.signal(n), t) for n in MIXER_INPUTS)])
    i_held = np.flatnonzero(held)
    starts = np.arange(0, len(i_held), BLOCK_SAMPLES)
    for k, name in enumerate(motors):
        sig = log.signal(name)
        y = hold(sig, t)
        c, *_ = np.linalg.lstsq(x[~held], y[~held], rcond=None)
        fit.coef_us[k] = c
        previous = hold(sig, t[i_held - 1])  # the output sample before each held-out one
        model = x[i_held] @ c
        s = skill_interval(y[i_held], model, previous, starts)
        fit.rmse_us.append(float(np.sqrt(np.mean((y[i_held] - model) ** 2))))
        fit.rmse_hold_us.append(float(np.sqrt(np.mean((y[i_held] - previous) ** 2))))
        fit.skill.append({"skill": s.skill, "lo": s.lo, "hi": s.hi})
    losers = [k + 1 for k, s in enumerate(fit.skill) if not s["lo"] > 0]
    fit.usable = not losers and fit.rate_hz > fit.output_hz
    if losers:
        fit.reason = (f"the RATE mixer inputs do not predict held-out outputs of motor(s) "
                      f"{', '.join(map(str, losers))} better than holding the previous output (thrust "
                      "linearisation, limits or a mixer this fit does not cover)")
    elif not fit.usable:
        fit.reason = f"RATE is logged at {fit.rate_hz:.0f} Hz, no faster than the motor outputs"
    return fit


def with_rebuilt_commands(log: FlightLog, fit: MixerFit) -> FlightLog:
    """A copy of ``log`` whose ``motor_<k>_pwm_us`` are the fit's commands at the RATE sample times (the logged
    outputs stay as ``motor_<k>_pwm_logged_us``)."""
    t = log.signal(MIXER_INPUTS[0]).t_s
    x = np.column_stack([np.ones(len(t)), *(log.signal(n).values for n in MIXER_INPUTS)])
    signals = dict(log.signals)
    for k in range(1, N_MOTORS + 1):
        name = f"motor_{k}_pwm_us"
        old = signals[name]
        signals[f"motor_{k}_pwm_logged_us"] = dataclasses.replace(old, name=f"motor_{k}_pwm_logged_us")
        signals[name] = Signal(name, t, x @ fit.coef_us[k - 1], "us",
                               f"rebuilt from the RATE mixer inputs, fitted on {old.description or name}")
    return dataclasses.replace(log, signals=signals, warnings=[*log.warnings, fit.summary()])


def fill_in(logs: list[FlightLog], command_hz: float, min_hz: float, notes: list[str]
            ) -> tuple[list[FlightLog], float, str]:
    """Logs whose motor outputs are slower than ``min_hz`` [Hz]: each one's commands rebuilt from its RATE mixer
    inputs where every log's fit is usable and its RATE at least ``min_hz`` (a note per log in ``notes``);
    else the logs unchanged with the reason why not. Returns ``(logs, command rate [Hz], reason)``."""
    fits = [reconstruct(log) for log in logs]
    why = []
    for log, fit in zip(logs, fits, strict=True):
        if fit is None:
            why.append(f"{log.source} has no RATE mixer inputs to rebuild them from")
        elif not fit.usable:
            why.append(f"{log.source}: {fit.reason}")
        elif fit.rate_hz < min_hz:
            why.append(f"{log.source}: RATE is logged at {fit.rate_hz:.0f} Hz, below {min_hz:g} Hz too")
    if why:
        return logs, command_hz, "; ".join(why)
    notes += [fit.summary() for fit in fits if fit is not None]
    return ([with_rebuilt_commands(log, fit) for log, fit in zip(logs, fits, strict=True) if fit is not None],
            min(fit.rate_hz for fit in fits if fit is not None), "")
