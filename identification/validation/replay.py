"""Replay a flight log's inputs through an FMU with FMPy and score its outputs against the log, beside the
simplest rivals.

Nothing of the Python model is imported: ``fmpy.simulate_fmu`` drives the FMU (``fmu_models.fmi.host``) with
the recorded inputs as a structured input array. The log is cut into windows of ``window_s`` seconds, each
re-initialised from the logged state (the usual way open-loop-unstable vehicles are judged; 0: one
full-length replay). Every signal is scored per window and over all scored windows pooled, beside two
baselines over the same samples: persistence (the logged value at the window start held) and the window mean
of the log. The verdict rules are those of :mod:`identification.validation.output_map`: a model that loses to
persistence fails. Windows where the vehicle is on the ground are not replayed unless ``include_ground``.
Prediction horizons (error at a lead time after each restart from the logged state) and a one-step check of
the force model (the FMU's accelerometer output for the logged state and inputs) come from the same replay.
"""

from __future__ import annotations

import hashlib
import itertools
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, model_validator

from fmu_models.config import ConfigError, Schema, validate_config
from fmu_models.fmi.host import FmuHost, FmuRunError
from fmu_models.quadrotor.constants import INIT_THRUST_NAMES, MOTOR_LAG_SETTLE_TAUS, N_MOTORS, PWM_IDLE_US
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.common.metrics import (
    VERDICTS,
    FitMetrics,
    MetricsError,
    Score,
    block_starts,
    fit_metrics,
    rmse,
    segment_metrics,
    segment_rmse,
    skill,
    skill_interval,
    window_baselines,
)
from identification.logs.flightlog import FlightLog, LogError
from identification.logs.log_state import (
    ground_samples,
    hold,
    initial_values_at,
    mapped_inputs,
    unwrapped_angle,
)
from identification.validation import start_fit
from identification.validation.input_check import BATTERY_INPUT, check_inputs
from identification.validation.output_map import SignalMap

WING_INPUTS = ("aileron_rad", "elevator_rad", "rudder_rad", "throttle")
ACCEL = ("accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2")
DEFAULT_HORIZONS_S = (0.1, 0.5, 1.0, 2.0)
#: motors at or below the FMU's idle PWM, and never below the F450 default idle (an identified model may put its
#: zero-thrust point lower than the PWM an autopilot spins its motors at when armed on the ground)
DEFAULT_IDLE_US = PWM_IDLE_US
#: bytes a replay holds per grid sample: an upper estimate of 20 float64 arrays per compared signal (measured,
#: model, baselines, masks, metric temporaries) and 50 for the grid, inputs and initial states
#: two-sided level and resamples of the skill interval a pass needs (seeded: a verdict is reproducible)
SKILL_LEVEL, SKILL_RESAMPLES = 0.90, 2000
#: bootstrap block length of a single full-length replay [s] (its persistence is one held value: blocks of
#: about the usual window length keep the serial correlation of its error)
FULL_LENGTH_BLOCK_S = 2.0
BYTES_PER_SAMPLE_SIGNAL = 160
BYTES_PER_SAMPLE_BASE = 400


class ValidationInputError(ValueError):
    """Validation inputs missing, mismatched or too large; the message names what and how to proceed.

    (Named apart from FMPy's ``ValidationError``, which reports modelDescription findings.)
    """


Horizon = Annotated[float, Field(gt=0, le=3600, allow_inf_nan=False)]
Seconds = Annotated[float, Field(ge=0, le=1e7, allow_inf_nan=False)]
MAX_SEGMENTS = 5000  #: most spans ``segments_s`` may list


class ValidationOptions(Schema):
    """Options that size a replay, range-checked before anything is allocated."""

    rate_hz: float = Field(50.0, gt=0, le=2000, allow_inf_nan=False)
    window_s: float = Field(2.0, ge=0, le=86400, allow_inf_nan=False)  # 0: one full-length replay
    horizons_s: list[Horizon] = Field(default_factory=lambda: list(DEFAULT_HORIZONS_S), max_length=32)
    include_ground: bool = False
    max_memory_mb: float = Field(2048.0, gt=0, le=1e6, allow_inf_nan=False)
    #: only windows wholly inside one of these (t0, t1) spans [s from the log start] are scored (empty: all);
    #: e.g. the held-out segments of an identification
    segments_s: list[tuple[Seconds, Seconds]] = Field(default_factory=list, max_length=MAX_SEGMENTS)
    #: a fixed wing's window start body velocity v, w: the one matching the logged specific force y, z at the
    #: restart ("force", ``identification.validation.start_fit``) or the GPS velocity's as logged ("logged")
    start_velocity: Literal["force", "logged"] = "force"

    @model_validator(mode="after")
    def _segments_ordered(self) -> ValidationOptions:
        bad = [f"{a:g}:{b:g}" for a, b in self.segments_s if not a < b]
        if bad:
            raise ValueError(f"segments_s {', '.join(bad[:5])} (allowed: t0 < t1)")
        return self

    @model_validator(mode="after")
    def _window_holds_two_samples(self) -> ValidationOptions:
        if 0 < self.window_s < 2.0 / self.rate_hz:
            raise ValueError(f"window_s = {self.window_s:g} s holds fewer than 2 samples at rate_hz = "
                             f"{self.rate_hz:g} (allowed: 0 for one full-length window, or >= {2 / self.rate_hz:g})")
        return self


def options(source: str = "validate options", **values: Any) -> ValidationOptions:
    """:class:`ValidationOptions` from keyword values (None dropped); ``ConfigError`` lists every problem."""
    return validate_config({k: v for k, v in values.items() if v is not None}, ValidationOptions, source)


@dataclass(frozen=True)
class HorizonRow:
    """Error at lead time ``horizon_s`` after each restart from the logged state, over ``n`` restarts."""

    horizon_s: float
    rmse: float
    rmse_persistence: float
    n: int

    @property
    def skill_persistence(self) -> float:
        return skill(self.rmse, self.rmse_persistence)

    def as_dict(self) -> dict[str, Any]:
        return {"horizon_s": self.horizon_s, "rmse": self.rmse, "rmse_persistence": self.rmse_persistence,
                "skill_persistence": self.skill_persistence, "n": self.n}


@dataclass
class ReplayResult:
    """Scored replay: per-signal model, measured and persistence values over the scored grid, metrics,
    baselines and verdicts (pooled and per window), horizons, the one-step force check, identities."""

    fmu: dict[str, Any]
    log: dict[str, Any]
    t_s: np.ndarray
    model: dict[str, np.ndarray]
    measured: dict[str, np.ndarray]
    windows: list[tuple[float, float]]
    window_metrics: list[dict[str, FitMetrics]]
    overall: dict[str, FitMetrics]
    maps: tuple[SignalMap, ...]
    start_values: dict[str, float] = field(default_factory=dict)
    scores: dict[str, Score] = field(default_factory=dict)
    window_scores: list[dict[str, Score]] = field(default_factory=list)
    included: list[bool] = field(default_factory=list)
    ground: dict[str, int] = field(default_factory=dict)
    gaps: dict[str, int] = field(default_factory=dict)
    persistence: dict[str, np.ndarray] = field(default_factory=dict)
    horizons: dict[str, list[HorizonRow]] = field(default_factory=dict)
    one_step: dict[str, Score] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)
    #: Monte Carlo bands and their coverage per signal (``identification.validation.mc_bands.Bands``; ``validate --mc``)
    bands: Any = None
    #: where ``battery_voltage_V`` came from when a battery-state model fed it
    #: (``identification.validation.replay_battery``)
    battery: dict[str, Any] | None = None
    #: logged inputs outside what the FMU was built for (``identification.validation.input_check.InputFinding``)
    input_checks: list[Any] = field(default_factory=list)
    #: restart-state noise std of the start values read from the specific force (``start_fit.StartFit.start_std``)
    start_std: dict[str, float] = field(default_factory=dict)

    @property
    def failed(self) -> list[str]:
        """Gated signals whose pooled verdict is FAIL."""
        return [m.fmu for m in self.maps if self.scores[m.fmu].verdict == "FAIL" and m.gate]

    @property
    def ties(self) -> list[str]:
        """Gated signals whose pooled verdict is a tie (beat persistence by a margin noise makes)."""
        return [m.fmu for m in self.maps if self.scores[m.fmu].verdict == "tie" and m.gate]

    @property
    def scored(self) -> list[str]:
        """Gated signals with a verdict (pass, FAIL or tie): a run where this is empty proved nothing."""
        return [m.fmu for m in self.maps if self.scores[m.fmu].verdict != "n/a" and m.gate]

    @property
    def band_misses(self) -> list[str]:
        """Gated signals whose Monte Carlo band covers far less or far more of the log than its nominal level
        (``identification.validation.mc_bands.Bands.verdict``: ``not explained`` or ``wide``)."""
        if self.bands is None:
            return []
        return [m.fmu for m in self.maps if m.gate and self.bands.verdict(m.fmu)[0] in ("not explained", "wide")]

    @property
    def status(self) -> str:
        """``fail`` (a gated signal fails), ``band`` (none fails, but a gated signal's prediction band misses its
        nominal coverage), ``tie`` (none fails, one ties), ``unscored`` (no gated signal has a verdict) or
        ``pass``."""
        if self.failed:
            return "fail"
        if self.band_misses:
            return "band"
        if self.ties:
            return "tie"
        return "pass" if self.scored else "unscored"

    @property
    def excluded(self) -> int:
        return sum(not k for k in self.included)

    def window_counts(self, name: str) -> dict[str, int]:
        """How many scored windows gave each verdict for signal ``name``."""
        out = dict.fromkeys(VERDICTS, 0)
        for w in self.window_scores:
            if name in w:
                out[w[name].verdict] += 1
        return out


def vehicle_of(host: FmuHost) -> str:
    """``quadrotor`` or ``fixed_wing`` from the FMU's inputs (``FmuHost.vehicle``)."""
    try:
        return host.vehicle
    except FmuRunError as err:
        raise ValidationInputError(str(err)) from None


def log_identity(log: FlightLog, path: Path) -> dict[str, Any]:
    digest = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else ""
    quality = getattr(log, "quality", None)
    return {"path": str(path), "format": log.fmt, "vehicle": log.vehicle, "duration_s": round(log.duration_s, 3),
            "sha256": digest, "warnings": list(log.warnings),
            "quality": quality.to_dict() if quality is not None else None,
            "quality_lines": list(quality.lines()) if quality is not None else []}


def fmu_identity(host: FmuHost, start_values: Mapping[str, float]) -> dict[str, Any]:
    params = {v.name: (float(start_values[v.name]) if v.name in start_values else float(v.start))
              for v in host.md.modelVariables
              if v.causality == "parameter" and v.type == "Real" and v.start is not None}
    return {"path": str(host.path), "model_name": host.md.modelName, "guid": host.md.guid,
            "generation_tool": host.md.generationTool, "generated": host.md.generationDateAndTime,
            "parameters": params, "overrides": dict(start_values)}


def log_inputs(vehicle: str, log: FlightLog, t_s: np.ndarray, mapping: PwmMapping | None) -> dict[str, np.ndarray]:
    """FMU inputs at ``t_s``: motor PWM for the quadrotor, mapped surface and throttle commands for the wing."""
    if vehicle == "quadrotor":
        return {f"pwm_{k}_us": hold(log.signal(f"motor_{k}_pwm_us"), t_s) for k in range(1, N_MOTORS + 1)}
    if mapping is None:
        mapping = PwmMapping.from_ardupilot(log.params)
    u = mapped_inputs(WING_INPUTS, log, mapping, t_s)
    return {n: u[:, i] for i, n in enumerate(WING_INPUTS)}


def other_inputs(host: FmuHost, log: FlightLog, t_s: np.ndarray, given: Mapping[str, np.ndarray]
                 ) -> tuple[dict[str, np.ndarray], list[str]]:
    """The FMU's remaining real inputs (e.g. battery voltage): from the log's signal of the same name (case
    aside) where logged, else held at the FMU's start value; with a note for each one held."""
    logged = {n.lower(): n for n in log.signals if "." not in n}
    out, notes = {}, []
    for name, v in host.variables.items():
        if v.causality != "input" or v.type != "Real" or name in given:
            continue
        if name.lower() in logged:
            out[name] = log.signal(logged[name.lower()]).resample(t_s)
        else:
            out[name] = np.full(len(t_s), host.start_value(name))
            notes.append(f"FMU input {name} is not in the log: held at its start value {host.start_value(name):g}")
    return out, notes


def _check_inputs(host: FmuHost, log: FlightLog, log_path: Path, maps: Sequence[SignalMap],
                  overrides: Mapping[str, float]) -> str:
    vehicle = vehicle_of(host)
    unknown = [n for n in overrides if n not in host.variables]
    if unknown:
        raise ValidationInputError(f"--set: {', '.join(unknown)} not variables of {host.path.name}")
    missing_out = [m.fmu for m in maps if m.fmu not in host.variables]
    if missing_out:
        raise ValidationInputError(f"output map: {', '.join(missing_out)} not outputs of {host.path.name}")
    absent = [m.log for m in maps if not log.has(m.log)]
    motors = [f"motor_{k}_pwm_us" for k in range(1, N_MOTORS + 1)] if vehicle == "quadrotor" else []
    absent_in = [n for n in motors if not log.has(n)]
    if absent or absent_in:
        what = [f"inputs {', '.join(absent_in)}"] if absent_in else []
        what += [f"output-map signals {', '.join(absent)}"] if absent else []
        raise ValidationInputError(f"{log_path}: missing logged {'; '.join(what)}")
    return vehicle


def memory_estimate_bytes(n_samples: int, n_signals: int) -> int:
    """Bytes a replay of ``n_samples`` grid samples and ``n_signals`` compared signals holds at its peak."""
    return int(n_samples) * (BYTES_PER_SAMPLE_BASE + BYTES_PER_SAMPLE_SIGNAL * max(1, n_signals))


def replay_grid(log: FlightLog, log_path: Path, vehicle: str, opts: ValidationOptions, n_signals: int,
                t_range: tuple[float, float] | None = None) -> np.ndarray:
    """The replay's time grid [s], after checking that it fits in ``opts.max_memory_mb`` (a log with a time
    jump, or a high rate, would otherwise allocate gigabytes before any message)."""
    first = log.signal("motor_1_pwm_us" if vehicle == "quadrotor" else "roll_rad")
    t0, t1 = (float(first.t_s[0]), float(first.t_s[-1])) if t_range is None else t_range
    dt = 1.0 / opts.rate_hz
    n = int(np.ceil((t1 - t0) / dt)) if t1 > t0 else 0  # np.arange(t0, t1, dt) without allocating first
    need = memory_estimate_bytes(n, n_signals)
    if need > opts.max_memory_mb * 2**20:
        raise ValidationInputError(
            f"{log_path}: the replay would need about {need / 2**20:,.0f} MB ({n:,} samples: the log spans "
            f"{t1 - t0:,.1f} s at rate_hz = {opts.rate_hz:g}), above the limit of {opts.max_memory_mb:g} MB. "
            "Lower --rate-hz, check the log for a time jump, or raise --max-memory-mb.")
    t = t0 + np.arange(n) * dt
    if len(t) < 3:
        raise ValidationInputError(f"{log_path}: fewer than 3 samples at {opts.rate_hz:g} Hz between {t0:g} and "
                                   f"{t1:g} s")
    return t


def _measured(maps: Sequence[SignalMap], log: FlightLog, t: np.ndarray, host: FmuHost,
              params: Mapping[str, float]) -> dict[str, np.ndarray]:
    """Log signals on the grid in the FMU's units; angles with ``wrap`` as one continuous series."""
    out = {}
    for m in maps:
        sig = log.signal(m.log)
        out[m.fmu] = m.convert(unwrapped_angle(sig, t) if m.wrap else sig.resample(t), host.unit(m.fmu), params)
    return out


def _ground_windows(log: FlightLog, vehicle: str, t: np.ndarray, edges: Sequence[int], idle_pwm_us: float
                    ) -> tuple[list[bool], dict[str, int]]:
    """Per window: on the ground at any of its samples; and for each criterion the windows it excludes."""
    masks = ground_samples(log, vehicle, t, idle_pwm_us)
    bounds = list(zip(edges[:-1], np.asarray(edges[1:]) + 1, strict=True))
    counts: dict[str, int] = {}
    any_ground = np.zeros(len(bounds), dtype=bool)
    for reason, mask in masks.items():
        hit = np.array([bool(mask[a:b].any()) for a, b in bounds], dtype=bool)
        counts[reason] = int(hit.sum())
        any_ground |= hit
    return [not g for g in any_ground], {k: v for k, v in counts.items() if v}


#: a logged signal with no sample for longer than this many of its median periods (and at least MIN_GAP_S)
#: has a gap: windows overlapping it are not scored (interpolation or a held value would invent the data)
GAP_PERIODS, MIN_GAP_S = 5.0, 0.5


def _coverage_windows(log: FlightLog, names: Sequence[str], t: np.ndarray, edges: Sequence[int]
                      ) -> tuple[list[bool], dict[str, int]]:
    """Per window: every signal of ``names`` has data throughout; and for each signal the windows it leaves
    without data (a gap, or the signal ends before the window or starts after it)."""
    ta, tb = t[np.asarray(edges[:-1])], t[np.asarray(edges[1:])]
    covered = np.ones(len(ta), dtype=bool)
    counts: dict[str, int] = {}
    for name in dict.fromkeys(names):
        ts = log.signal(name).t_s
        if len(ts) < 2:
            continue
        dt = np.diff(ts)
        limit = max(MIN_GAP_S, GAP_PERIODS * float(np.median(dt)))
        big = np.flatnonzero(dt > limit)
        lo = np.concatenate([[-np.inf], ts[big], [ts[-1] + limit]])
        hi = np.concatenate([[ts[0] - limit], ts[big + 1], [np.inf]])
        # a window [ta, tb] misses data when it overlaps any hole (lo, hi)
        first = np.searchsorted(hi, ta, side="right")  # first hole ending after the window starts
        miss = (first < len(lo)) & (lo[np.minimum(first, len(lo) - 1)] < tb)
        if miss.any():
            counts[f"no data for {name}"] = int(miss.sum())
            covered &= ~miss
    return [bool(c) for c in covered], counts


def _simulate_windows(host: FmuHost, t: np.ndarray, inputs: Mapping[str, np.ndarray], maps: Sequence[SignalMap],
                      measured: Mapping[str, np.ndarray], starts: list[dict[str, float]], edges: Sequence[int],
                      included: Sequence[bool], extra: Sequence[str],
                      progress: Callable[[int, int], None] | None) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Model outputs on the grid (NaN outside the included windows' predicted samples) and the FMU's
    ``extra`` outputs at each included window's start (the one-step check), NaN for excluded windows."""
    n = len(t)
    model = {m.fmu: np.full(n, np.nan) for m in maps}
    first = np.full((len(edges) - 1, len(extra)), np.nan)
    names = [m.fmu for m in maps] + [e for e in extra if e not in {m.fmu for m in maps}]
    for i, (a, b) in enumerate(itertools.pairwise(edges)):
        if included[i]:
            start = {**starts[i], **lagged_thrust(host, t, inputs, a, starts[i])}
            res = host.simulate(t[a:b + 1], {k: v[a:b + 1] for k, v in inputs.items()}, names, start)
            for m in maps:  # sample a is the re-initialisation itself: score the predicted samples a+1..b
                model[m.fmu][a + 1:b + 1] = m.align(res[m.fmu][1:], measured[m.fmu][a + 1:b + 1])
            first[i] = [res[e][0] for e in extra]
        if progress:
            progress(i + 1, len(edges) - 1)
    return model, first


#: a quadrotor restart's motor lags are run over ``MOTOR_LAG_SETTLE_TAUS`` motor time constants of the logged
#: commands before it, and at most this long [s]
LAG_WARMUP_MAX_S = 2.0
INIT_THRUST = INIT_THRUST_NAMES


def lagged_thrust(host: FmuHost, t: np.ndarray, inputs: Mapping[str, np.ndarray], a: int,
                  start: Mapping[str, float]) -> dict[str, float]:
    """``init_thrust_<k>_N`` [N] of a restart at grid sample ``a``: the thrust each motor lags at there.

    A restart in the middle of a manoeuvre otherwise begins with every motor at the thrust its PWM commands, as
    if the commands had been steady for ever: with a 25 ms motor lag and a rate loop swinging the commands, the
    moment of that false start alone loses a 0.5 s replay of the body rates. The FMU's own motor lag (its
    thrust outputs, which depend on the PWM and voltage inputs alone) is run over the grid's inputs of the
    ``MOTOR_LAG_SETTLE_TAUS`` time constants before ``a`` (``start`` gives ``tau_motor_s`` and the body state, which
    the thrust does not depend on). Empty when the FMU has no such parameters (built before them), no motor
    lag, or no sample before ``a``."""
    if INIT_THRUST[0] not in host.variables or a < 1:
        return {}
    tau = float(start.get("tau_motor_s", host.start_value("tau_motor_s")))
    dt = float(t[1] - t[0])
    if not tau > 0:
        return {}
    k = min(a, max(1, int(np.ceil(min(MOTOR_LAG_SETTLE_TAUS * tau, LAG_WARMUP_MAX_S) / dt))))
    outs = [f"thrust_{j}_N" for j in range(1, N_MOTORS + 1)]
    res = host.simulate(t[a - k:a + 1], {n: v[a - k:a + 1] for n, v in inputs.items()}, outs,
                        {**start, **dict.fromkeys(INIT_THRUST, -1.0)})
    return {p: float(res[o][-1]) for p, o in zip(INIT_THRUST, outs, strict=True)}


def _windows_to_score(log: FlightLog, log_path: Path, vehicle: str, maps: Sequence[SignalMap],
                      mapping: PwmMapping | None, t: np.ndarray, edges: Sequence[int], opts: ValidationOptions,
                      idle_pwm_us: float) -> tuple[list[bool], dict[str, int], dict[str, int], np.ndarray | None]:
    """Which windows are scored: not on the ground (unless ``include_ground``; a single full-length window
    instead leaves out its ground samples, returned as a mask) and with data for every input and compared
    signal. Returns (included, ground reasons, gap reasons, ground-sample mask or None)."""
    included, ground, on_ground = [True] * (len(edges) - 1), {}, None
    if not opts.include_ground and len(edges) == 2:
        masks = ground_samples(log, vehicle, t, idle_pwm_us)
        on_ground = np.any(list(masks.values()), axis=0) if masks else None
        ground = {f"{k} (samples)": int(v.sum()) for k, v in masks.items() if v.any()}
    elif not opts.include_ground:
        included, ground = _ground_windows(log, vehicle, t, edges, idle_pwm_us)
    used = [f"motor_{k}_pwm_us" for k in range(1, N_MOTORS + 1)] if vehicle == "quadrotor" else \
        [f"servo_{c.source}_pwm_us" for c in (mapping or PwmMapping.from_ardupilot(log.params)).channels
         if c.target in WING_INPUTS and log.has(f"servo_{c.source}_pwm_us")]
    covered, gaps = _coverage_windows(log, [*used, *(m.log for m in maps)], t, edges)
    included = [a and b for a, b in zip(included, covered, strict=True)]
    if not any(included):
        hint = "; use --include-ground to score ground windows" if ground else ""
        raise ValidationInputError(f"{log_path}: no replay window left to score ({'; '.join([*ground, *gaps])})"
                                   + hint)
    if on_ground is not None and on_ground[1:].all():
        raise ValidationInputError(f"{log_path}: the vehicle is on the ground throughout; use --include-ground")
    return included, ground, gaps, on_ground


@dataclass
class ReplaySetup:
    """Everything a replay simulates from: the grid [s], FMU inputs on it, the log's compared signals in FMU
    units, window edges (grid indices), which windows are scored and why not, each window's logged start
    state, the FMU's parameters (overrides applied), and notes on inputs held at their start value."""

    vehicle: str
    t: np.ndarray
    inputs: dict[str, np.ndarray]
    measured: dict[str, np.ndarray]
    edges: list[int]
    included: list[bool]
    ground: dict[str, int]
    gaps: dict[str, int]
    on_ground: np.ndarray | None
    starts: list[dict[str, float]]
    extra: list[str]
    params: dict[str, float]
    notes: list[str]
    opts: ValidationOptions
    battery: dict[str, Any] | None = None
    #: logged inputs outside what the FMU was built for (``identification.validation.input_check``)
    input_checks: list[Any] = field(default_factory=list)
    #: the fixed wing's start velocities read from the specific force (``start_fit.StartFit``), when they were
    start_fit: Any = None


def replay_setup(host: FmuHost, log: FlightLog, log_path: Path, maps: Sequence[SignalMap], opts: ValidationOptions,
                 overrides: Mapping[str, float], mapping: PwmMapping | None = None,
                 t_range: tuple[float, float] | None = None, battery: Any = None) -> ReplaySetup:
    """Check the inputs and build the grid, inputs, windows and start states of a replay (nothing simulated);
    ``battery`` (``identification.validation.replay_battery.BatteryStateModel``) drives ``battery_voltage_V``."""
    vehicle = _check_inputs(host, log, log_path, maps, overrides)
    t = replay_grid(log, log_path, vehicle, opts, len(maps), t_range)
    try:
        inputs = log_inputs(vehicle, log, t, mapping)
    except LogError as err:
        raise ValidationInputError(str(err)) from err
    more, notes = other_inputs(host, log, t, inputs)
    inputs.update(more)
    if vehicle == "quadrotor":
        notes += command_rate_notes(log, opts.rate_hz)
    params = {n: host.start_value(n) for n, v in host.variables.items() if v.causality == "parameter"}
    params.update(overrides)
    source = None
    if battery is not None:
        from identification.validation.replay_battery import feed

        try:
            source = feed(battery, vehicle, params, log, t, inputs, notes)
        except ValueError as err:
            raise ValidationInputError(f"{log_path}: {err}") from err
    fed = _set_inputs(host, inputs, overrides, notes)
    if source is not None and source.get("source") != "logged":
        fed.setdefault(BATTERY_INPUT, f"{source['source']} ({source['detail']})")
    measured = _measured(maps, log, t, host, params)
    n = len(t)
    step = n - 1 if not opts.window_s else max(1, round(opts.window_s * opts.rate_hz))
    edges = [*range(0, n - 1, step), n - 1]
    included, ground, gaps, on_ground = _windows_to_score(log, log_path, vehicle, maps, mapping, t, edges, opts,
                                                          max(params.get("pwm_idle_us", 0.0), DEFAULT_IDLE_US))
    if opts.segments_s:
        spans: list[list[float]] = []
        for a, b in sorted(opts.segments_s):  # touching spans (a segment given as its windows) join
            if spans and a <= spans[-1][1] + 1e-6:
                spans[-1][1] = max(spans[-1][1], b)
            else:
                spans.append([a, b])
        inside = [any(a <= t[e0] + 1e-9 and t[e1] <= b + 1e-9 for a, b in spans)
                  for e0, e1 in itertools.pairwise(edges)]
        outside = sum(1 for i, k in zip(included, inside, strict=True) if i and not k)
        included = [i and k for i, k in zip(included, inside, strict=True)]
        if outside:
            gaps = {**gaps, "outside the given segments": outside}
        if not any(included):
            raise ValidationInputError(f"{log_path}: no replay window lies wholly inside the given segments "
                                       f"(windows of {opts.window_s:g} s)")
    starts = [{**s, **overrides} for s in initial_values_at(log, t[edges[:-1]],
                                                            forward_from_airspeed=vehicle == "fixed_wing")]
    extra = [a for a in ACCEL if a in host.variables and log.has(a)]
    fitted = None
    if (opts.start_velocity == "force" and start_fit.applies(host, log, vehicle)
            and not any(n in overrides for n in start_fit.UNKNOWNS)):  # a start velocity given by --set stays
        fitted = start_fit.force_consistent_starts(host, log, t, inputs, edges, included, starts, extra)
        starts = fitted.starts
        if fitted.note():
            notes.append(str(fitted.note()))
    scored = np.repeat(np.asarray(included), np.diff(edges))
    scored = np.append(scored, scored[-1])
    if on_ground is not None:
        scored &= ~on_ground
    from identification.validation.replay_battery import LOGGED

    logged_v = log.signal(LOGGED).resample(t) if log.has(LOGGED) else None
    findings = check_inputs(vehicle, inputs, _servo_pwm(vehicle, log, mapping, t), params, logged_v, fed, scored)
    return ReplaySetup(vehicle, t, inputs, measured, edges, included, ground, gaps, on_ground, starts, extra, params,
                       notes, opts, source, findings, fitted)


#: motor commands logged more than this many times faster than the replay grid are named in a note
COMMAND_RATE_MARGIN = 1.5


def command_rate_notes(log: FlightLog, rate_hz: float) -> list[str]:
    """A note when the log records motor commands much faster than the replay grid [Hz]: the grid holds one
    command per step, so a rate loop's changes in between never reach the FMU."""
    d = np.diff(log.signal("motor_1_pwm_us").t_s)
    d = d[d > 0]
    if not d.size or 1.0 / np.median(d) <= COMMAND_RATE_MARGIN * rate_hz:
        return []
    hz = float(1.0 / np.median(d))
    return [f"motor commands logged at {hz:.0f} Hz, replayed on a {rate_hz:g} Hz grid: each one held "
            f"{1000.0 / rate_hz:g} ms, the commands in between are not replayed (--rate-hz {hz:.0f} replays them)"]


def _set_inputs(host: FmuHost, inputs: dict[str, np.ndarray], overrides: Mapping[str, float], notes: list[str]
                ) -> dict[str, str]:
    """Feed every FMU input named in ``overrides`` (``--set``) as that constant instead of the log; what was fed
    per input (an input's start value alone would be overwritten by the logged series)."""
    fed = {}
    for name, value in overrides.items():
        v = host.variables.get(name)
        if v is None or v.causality != "input" or name not in inputs:
            continue
        inputs[name] = np.full(len(next(iter(inputs.values()))), float(value))
        fed[name] = f"{float(value):g} (--set {name}) instead of the log"
        notes[:] = [n for n in notes if not n.startswith(f"FMU input {name} ")]
        notes.append(f"FMU input {name} fed {float(value):g} from --set, not from the log")
    return fed


def _servo_pwm(vehicle: str, log: FlightLog, mapping: PwmMapping | None, t: np.ndarray
               ) -> dict[str, tuple[np.ndarray, tuple[float, float, str]]]:
    """Per fixed-wing input: its logged servo PWM on the grid and the mapping channel's range."""
    if vehicle != "fixed_wing":
        return {}
    m = mapping or PwmMapping.from_ardupilot(log.params)
    return {c.target: (hold(log.signal(f"servo_{c.source}_pwm_us"), t),
                       (c.min_us, c.max_us, f"mapping channel {c.source} min_us..max_us"))
            for c in m.channels if c.target in WING_INPUTS and log.has(f"servo_{c.source}_pwm_us")}


def simulate_setup(host: FmuHost, setup: ReplaySetup, maps: Sequence[SignalMap],
                   starts: list[dict[str, float]] | None = None,
                   progress: Callable[[int, int], None] | None = None) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Model outputs on the grid of ``setup`` (NaN where not scored) from its, or the given, window starts, and
    the ``extra`` outputs at each window start."""
    s = setup
    model, first = _simulate_windows(host, s.t, s.inputs, maps, s.measured, starts or s.starts, s.edges, s.included,
                                     s.extra, progress)
    if s.on_ground is not None:
        for v in model.values():
            v[s.on_ground] = np.nan
    return model, first


def replay(host: FmuHost, log: FlightLog, log_path: Path, maps: Sequence[SignalMap], rate_hz: float = 50.0,
           window_s: float | None = 2.0, start_values: Mapping[str, float] | None = None,
           mapping: PwmMapping | None = None, t_range: tuple[float, float] | None = None,
           progress: Callable[[int, int], None] | None = None, *, include_ground: bool = False,
           horizons_s: Sequence[float] = DEFAULT_HORIZONS_S, max_memory_mb: float = 2048.0,
           battery: Any = None, segments_s: Sequence[tuple[float, float]] = (),
           start_velocity: str = "force") -> ReplayResult:
    """Replay ``log`` through the FMU of ``host`` on a ``rate_hz`` grid and score the signals of ``maps``
    (``battery``: see :func:`replay_setup`; ``segments_s``, ``start_velocity``: see :class:`ValidationOptions`)."""
    opts = options(rate_hz=rate_hz, window_s=window_s or 0.0, include_ground=include_ground,
                   horizons_s=list(horizons_s), max_memory_mb=max_memory_mb, segments_s=list(segments_s),
                   start_velocity=start_velocity)
    overrides = dict(start_values or {})
    s = replay_setup(host, log, log_path, maps, opts, overrides, mapping, t_range, battery)
    t, edges, measured = s.t, s.edges, s.measured
    model, first = simulate_setup(host, s, maps, progress=progress)
    res = ReplayResult(fmu_identity(host, overrides), log_identity(log, log_path), t[1:],
                       {k: v[1:] for k, v in model.items()}, {k: v[1:] for k, v in measured.items()},
                       [(float(t[a]), float(t[b])) for a, b in itertools.pairwise(edges)],
                       [], {}, tuple(maps), overrides, included=list(s.included), ground=s.ground, gaps=s.gaps,
                       options=opts.model_dump(), battery=s.battery, input_checks=list(s.input_checks),
                       start_std=dict(s.start_fit.start_std) if s.start_fit is not None else {})
    res.log["warnings"] += s.notes
    score(res, np.asarray(edges), {m.fmu: measured[m.fmu][edges[:-1]] for m in maps})
    res.horizons = _horizons(maps, measured, model, edges, s.included, opts)
    if s.start_fit is not None:  # the force model at the logged start (at the fitted one y, z match by construction)
        first = np.where(np.isnan(s.start_fit.logged_first), first, s.start_fit.logged_first)
    res.one_step = _one_step(log, t[edges[:-1]], first, s.extra)
    return res


def score(res: ReplayResult, edges: np.ndarray, init: Mapping[str, np.ndarray]) -> None:
    """Fill ``res`` with pooled and per-window metrics, baselines and verdicts of the included windows.

    ``res.model``/``res.measured`` hold the grid after its first sample, ``edges`` the window edges on the grid,
    ``init`` each signal's logged value at each window start. The pooled verdict needs the skill against
    persistence above ``min_skill_persistence`` over its whole block-bootstrap interval (blocks: the scored
    windows; a single full-length window is cut into blocks of ``FULL_LENGTH_BLOCK_S``), else it is a tie."""
    starts = edges[:-1]
    counts = np.diff(edges)
    keep = np.repeat(np.asarray(res.included), counts)
    inc = np.flatnonzero(res.included)
    starts_c = np.concatenate([[0], np.cumsum(counts[inc])[:-1]]).astype(int)
    blocks = starts_c if len(starts_c) >= 2 else \
        block_starts(int(counts[inc].sum()), max(2, round(FULL_LENGTH_BLOCK_S * res.options.get("rate_hz", 50.0))))
    per_window: dict[str, tuple[list[FitMetrics], np.ndarray, np.ndarray]] = {}
    for m in res.maps:
        y = res.measured[m.fmu]
        pers, mean = window_baselines(y, starts, init[m.fmu])
        res.persistence[m.fmu] = np.where(keep, pers, np.nan)
        y_c, m_c, p_c, w_c = y[keep], res.model[m.fmu][keep], pers[keep], mean[keep]
        try:
            fit = fit_metrics(y_c, m_c)
        except MetricsError as err:
            raise ValidationInputError(f"{m.fmu}: {err} (no finite FMU value in the scored windows)") from None
        rp, rm = rmse(y_c, p_c), rmse(y_c, w_c)
        res.overall[m.fmu] = fit
        band = skill_interval(y_c, m_c, p_c, blocks, level=SKILL_LEVEL, n_boot=SKILL_RESAMPLES)
        res.scores[m.fmu] = Score(fit, rp, rm, *m.judge(fit, rp, rm, band), gated=m.gate, interval=band)
        per_window[m.fmu] = (segment_metrics(y_c, m_c, starts_c), segment_rmse(y_c, p_c, starts_c),
                             segment_rmse(y_c, w_c, starts_c))
    res.window_metrics, res.window_scores = [], []
    slot = {int(w): k for k, w in enumerate(inc)}
    maps = {m.fmu: m for m in res.maps}
    for i in range(len(res.windows)):
        if i not in slot:
            res.window_metrics.append({})
            res.window_scores.append({})
            continue
        k = slot[i]
        fits = {s: v[0][k] for s, v in per_window.items()}
        res.window_metrics.append(fits)
        res.window_scores.append({s: Score(fits[s], float(v[1][k]), float(v[2][k]),
                                           *maps[s].judge(fits[s], float(v[1][k]), float(v[2][k])),
                                           gated=maps[s].gate)
                                  for s, v in per_window.items()})


def _horizons(maps: Sequence[SignalMap], measured: Mapping[str, np.ndarray], model: Mapping[str, np.ndarray],
              edges: Sequence[int], included: Sequence[bool], opts: ValidationOptions) -> dict[str, list[HorizonRow]]:
    """Error at each lead time after the restarts of the included windows (horizons longer than a window are
    left out: each restart runs one window)."""
    a = np.asarray(edges[:-1])[np.asarray(included)]
    b = np.asarray(edges[1:])[np.asarray(included)]
    out: dict[str, list[HorizonRow]] = {m.fmu: [] for m in maps}
    for h in sorted(opts.horizons_s):
        k = round(h * opts.rate_hz)
        ok = (k >= 1) & (a + k <= b)
        if not np.any(ok):
            continue
        idx, base = a[ok] + k, a[ok]
        for m in maps:
            y = measured[m.fmu]
            out[m.fmu].append(HorizonRow(float(h), rmse(y[idx], model[m.fmu][idx]), rmse(y[idx], y[base]),
                                         int(ok.sum())))
    return out


def _one_step(log: FlightLog, t0: np.ndarray, first: np.ndarray, extra: Sequence[str]) -> dict[str, Score]:
    """The FMU's specific force for the logged state and inputs at each restart against the logged
    accelerometer: a wrong force model shows here, a drifting integration does not. Baseline: the log's mean
    over the same instants (persistence has no meaning at zero lead)."""
    out: dict[str, Score] = {}
    for j, name in enumerate(extra):
        y = log.signal(name).resample(t0)
        ok = np.isfinite(first[:, j])
        if ok.sum() < 2:
            continue
        mean = np.full(int(ok.sum()), float(np.mean(y[ok])))
        fit = fit_metrics(y[ok], first[ok, j])
        base = rmse(y[ok], mean)
        band = skill_interval(y[ok], first[ok, j], mean, np.arange(int(ok.sum())), SKILL_LEVEL, SKILL_RESAMPLES)
        verdict = "FAIL" if not band.skill > 0 else ("pass" if band.outcome == "win" else "tie")
        words = {"pass": "beats", "FAIL": "loses to", "tie": "is no better with confidence than"}[verdict]
        reason = (f"force model {words} the log's mean specific force (skill {band.skill:+.2f}, "
                  f"{100 * band.level:.0f} % interval {band.lo:+.2f}..{band.hi:+.2f} over {band.n_blocks} restarts)")
        out[name] = Score(fit, float("nan"), base, verdict, reason, gated=False, interval=band)
    return out


def check_options(**values: Any) -> ValidationOptions:
    """Range-checked options; ``ValidationInputError`` with one line per problem named as its command-line
    option (never a traceback)."""
    try:
        return options("options", **values)
    except ConfigError as err:
        lines = [re.sub(r"^field (\w+)", lambda g: "--" + g.group(1).replace("_", "-"), p) for p in err.problems]
        raise ValidationInputError("; ".join(lines)) from None
