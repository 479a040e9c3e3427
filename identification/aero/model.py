"""From a fixed-wing flight log to output-error manoeuvres, and back to scored model outputs.

Inputs come from the log's servo PWM through :mod:`fmu_models.signals.pwm_mapping` (the same mapping the HIL
adapter drives the FMU with; ArduPilot ``SERVOn_*`` parameters in the log fill it). Measured outputs are
the log's canonical signals (``identification.logs.flightlog``), resampled onto a uniform grid. Each segment
starts from the log's own state at its first sample: attitude, body rates, altitude, and the body velocity
from GPS velocity where logged, else the airspeed along body x.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from fmu_models.common.model import VehicleModel, init_function
from fmu_models.signals.names import FIXED_WING_FIT_OUTPUTS, OUTPUT_TO_LOG
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.common.metrics import FitMetrics, fit_metrics
from identification.estimation.oem import Manoeuvre
from identification.estimation.unlogged_inputs import Unlogged
from identification.logs.flightlog import FlightLog, LogError
from identification.logs.log_state import (
    START_SIGNALS,
    initial_values,
    initial_values_from,
    interpolation_variance_factor,
    mapped_inputs,
    noise_std,
    start_signal_values,
)
from identification.logs.sensor_chain import LoopClock
from identification.logs.timeline import SpanError, parse_spans

#: outputs fitted by default: attitude, body rates, specific force, airspeed
DEFAULT_OUTPUTS = FIXED_WING_FIT_OUTPUTS
#: the roll-axis subset of paper 001's Fig. 1
ROLL_OUTPUTS = ("roll_rad", "rate_body_x_rad_s")


class SegmentError(ValueError):
    """A segment specification that does not parse or lies outside the log."""


@dataclass(frozen=True)
class Segment:
    t0_s: float
    t1_s: float

    def __str__(self) -> str:
        return f"{self.t0_s:g}:{self.t1_s:g}"


def parse_segments(text: str, option: str = "--segments") -> list[Segment]:
    """``"t0:t1,t0:t1"`` (seconds from log start) into segments; errors name the option and the item."""
    try:
        out = [Segment(a, b) for a, b in parse_spans(text, option)]
    except SpanError as err:
        raise SegmentError(str(err)) from None
    if not out:
        raise SegmentError(f"{option}: no segment in {text!r}")
    return out


def grid(segment: Segment, rate_hz: float) -> np.ndarray:
    """Sample times of a segment: ``t0, t0 + dt, ...`` up to ``t1``."""
    n = math.floor((segment.t1_s - segment.t0_s) * rate_hz + 1e-9)
    return segment.t0_s + np.arange(n + 1) / rate_hz


def log_inputs(model: VehicleModel, log: FlightLog, mapping: PwmMapping, t_s: np.ndarray,
               clock: LoopClock | None = None) -> np.ndarray:
    """Model inputs (len(t) x nu) from the servo PWM at times ``t_s``: zero-order hold of the log samples, or with
    ``clock`` the command of the loop acting at each time (``LoopClock.commands``)."""
    if clock is None:
        return mapped_inputs(list(model.inputs.index), log, mapping, t_s)
    return mapped_inputs(list(model.inputs.index), log, mapping, t_s,
                         lambda sig, t: clock.commands(sig.t_s, sig.values, t))


def log_outputs(log: FlightLog, outputs: Sequence[str], t_s: np.ndarray) -> np.ndarray:
    """Measured outputs (len(t) x ny) at ``t_s``, linearly interpolated."""
    unknown = [n for n in outputs if n not in OUTPUT_TO_LOG]
    if unknown:
        raise LogError(f"no log signal is known for the outputs {', '.join(unknown)}; "
                       f"choose from {', '.join(OUTPUT_TO_LOG)}")
    return np.column_stack([log.signal(OUTPUT_TO_LOG[n]).resample(t_s) for n in outputs])


def initial_state(model: VehicleModel, p: np.ndarray, log: FlightLog, t0_s: float, u0: np.ndarray,
                  init: ca.Function | None = None) -> np.ndarray:
    """The model state at ``t0_s`` from the log, through the model's own initial-state function (``init``:
    ``init_function(model)``, built once by the caller when it needs many states)."""
    return state_from(model, p, initial_values(log, t0_s, forward_from_airspeed=True), u0, init)


def state_from(model: VehicleModel, p: np.ndarray, init_values: dict[str, float], u0: np.ndarray,
               init: ca.Function | None = None) -> np.ndarray:
    """The model state from its ``init_*`` parameters ``init_values`` (``log_state.initial_values_from``) and the
    first input ``u0``, through the model's own initial-state function (``init``: ``init_function(model)``)."""
    q = p.copy()
    for name, value in init_values.items():
        q[model.params.index[name]] = value
    x0, _ = (init or init_function(model))(u0, q)
    return np.asarray(x0, dtype=float).ravel()


def loop_clock_for(clock: LoopClock | None, rate_hz: float) -> LoopClock | None:
    """``clock`` where the grid steps on the autopilot's loop ticks: ``rate_hz`` within 10 % of its loop rate;
    else None (the fixed grid of :func:`grid`)."""
    return None if clock is None or abs(clock.period_s * rate_hz - 1.0) > 0.1 else clock


def segment_grid(segment: Segment, rate_hz: float, clock: LoopClock | None = None) -> np.ndarray:
    """The sample times a segment is fitted on: :func:`grid`, or the loop ticks of ``clock``
    (:func:`loop_clock_for`)."""
    clock = loop_clock_for(clock, rate_hz)
    return grid(segment, rate_hz) if clock is None else clock.grid(segment.t0_s, segment.t1_s)


def manoeuvres(model: VehicleModel, p: np.ndarray, log: FlightLog, mapping: PwmMapping,
               segments: Sequence[Segment], outputs: Sequence[str], rate_hz: float,
               input_delay_s: float = 0.0, clock: LoopClock | None = None) -> list[Manoeuvre]:
    """One :class:`Manoeuvre` per segment: inputs at ``t_k``, measurements at ``t_{k+1}``; with
    ``input_delay_s`` the surfaces act the logged command of ``t_k - delay`` (command -> surface lag). With
    ``clock`` (the autopilot's loop ticks, ``rate_hz`` within 10 % of its loop rate) the grid steps on the ticks
    and each step holds that loop's command (``identification.logs.sensor_chain``)."""
    clock = loop_clock_for(clock, rate_hz)
    out = []
    end = log.duration_s
    init = init_function(model)
    for seg in segments:
        if seg.t1_s > end + 1e-6:
            raise SegmentError(f"{log.source}: segment {seg} ends after the log ({end:.2f} s)")
        t = segment_grid(seg, rate_hz, clock)
        if len(t) < 3:
            raise SegmentError(f"segment {seg} holds fewer than 3 samples at {rate_hz:g} Hz")
        u = log_inputs(model, log, mapping, np.maximum(t[:-1] - input_delay_s, 0.0), clock)
        y = log_outputs(log, outputs, t[1:])
        if not np.all(np.isfinite(y)):
            bad = [outputs[i] for i in range(len(outputs)) if not np.all(np.isfinite(y[:, i]))]
            raise LogError(f"{log.source}: segment {seg}: {', '.join(bad)} not finite (gap in the log?)")
        x0 = initial_state(model, p, log, float(t[0]), u[0], init)
        out.append(Manoeuvre(x0, u, y, 1.0 / rate_hz if clock is None else clock.period_s, str(seg)))
    return out


def start_noise(log: FlightLog, windows: Sequence[tuple[float, float]]) -> dict[str, float]:
    """Per logged signal a start state is read from (``log_state.start_signal_values``), the white
    noise std [its unit] inside ``windows`` ([t0, t1] s; ``log_state.noise_std``)."""
    used = start_signal_values(log, np.array([windows[0][0] if windows else 0.0]), True)
    return {n: noise_std(log.signal(n), windows) for n in START_SIGNALS if n in used}


def start_covariance(model: VehicleModel, p: np.ndarray, log: FlightLog, t0_s: float, u0: np.ndarray,
                     noise: dict[str, float], init: ca.Function | None = None) -> np.ndarray:
    """Covariance (nx x nx) of the model state :func:`initial_state` reads at ``t0_s`` about the true one, from
    the white noise of the logged signals it is read from (``noise``: signal -> std, :func:`start_noise`; each
    value interpolated between two samples, ``log_state.interpolation_variance_factor``): ``J diag(var) Jᵀ`` with
    ``J`` the state's central-difference derivative by those values (the attitude's noise turns the GPS velocity
    into the body axes: at 27 m/s a pitch noise of 0.003 rad is 0.08 m/s of vertical body velocity)."""
    fn = init or init_function(model)
    vals = {n: float(v[0]) for n, v in start_signal_values(log, np.array([t0_s]), True).items()}

    def x0_of(v: dict[str, float]) -> np.ndarray:
        return state_from(model, p, initial_values_from(v), u0, fn)

    names = [n for n in vals if noise.get(n, 0.0) > 0.0]
    nx = len(model.states.index)
    jac, var = np.zeros((nx, len(names))), np.zeros(len(names))
    for i, n in enumerate(names):
        h = 1e-3 * noise[n]
        up, down = dict(vals), dict(vals)
        up[n] += h
        down[n] -= h
        jac[:, i] = (x0_of(up) - x0_of(down)) / (2.0 * h)
        var[i] = noise[n] ** 2 * interpolation_variance_factor(log.signal(n), t0_s)
    return (jac * var) @ jac.T


def unlogged_brackets(model: VehicleModel, log: FlightLog, mapping: PwmMapping, segments: Sequence[Segment],
                      clock: LoopClock, input_delay_s: float = 0.0) -> list[Unlogged]:
    """Per segment (on the grid :func:`manoeuvres` builds with ``clock``): each loop's command bracketed by its
    logged neighbours, in model inputs, and whether that loop was logged (``LoopClock.bracket``)."""
    names = list(model.inputs.index)
    by_target = {c.target: c for c in mapping.channels}
    out = []
    for seg in segments:
        t = np.maximum(clock.grid(seg.t0_s, seg.t1_s)[:-1] - input_delay_s, 0.0)
        before, after = (mapped_inputs(names, log, mapping, t,
                                       lambda sig, q, i=i: clock.bracket(sig.t_s, sig.values, q)[i]) for i in (0, 1))
        logged = np.column_stack([clock.bracket(log.signal(f"servo_{by_target[n].source}_pwm_us").t_s,
                                                log.signal(f"servo_{by_target[n].source}_pwm_us").values, t)[3]
                                  for n in names])
        out.append(Unlogged(before, after, logged))
    return out


def score(measured: np.ndarray, model: np.ndarray, outputs: Sequence[str]) -> dict[str, FitMetrics]:
    """Fit metrics per output over all given samples."""
    return {n: fit_metrics(measured[:, i], model[:, i]) for i, n in enumerate(outputs)}
