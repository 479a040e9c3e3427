"""Replay a flight log's inputs through an FMU with FMPy and score its outputs against the log.

Nothing of the Python model is imported: ``fmpy.simulate_fmu`` drives the FMU (``fmu_models.fmi.host``) with
the recorded inputs as a structured input array. Full-length replay, or segment-wise replay in windows each
re-initialised from the logged state (the usual way open-loop-unstable vehicles are judged), scored per
window and over all windows together.
"""

from __future__ import annotations

import hashlib
import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fmu_models.fmi.host import FmuHost, FmuRunError
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.flightlog import FlightLog, LogError
from identification.log_state import hold, initial_values_at, mapped_inputs, resample_angle
from identification.metrics import FitMetrics, fit_metrics, segment_metrics
from identification.output_map import SignalMap

WING_INPUTS = ("aileron_rad", "elevator_rad", "rudder_rad", "throttle")


class ValidationError(ValueError):
    """Inputs or signals missing or mismatched; the message names what."""


@dataclass
class ReplayResult:
    """Scored replay: per-signal model and measured values over the scored samples, metrics, identities."""

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

    @property
    def failed(self) -> list[str]:
        return [m.fmu for m in self.maps if not m.passes(self.overall[m.fmu].theil_u, self.overall[m.fmu].rmse)]


def vehicle_of(host: FmuHost) -> str:
    """``quadrotor`` or ``fixed_wing`` from the FMU's inputs (``FmuHost.vehicle``)."""
    try:
        return host.vehicle
    except FmuRunError as err:
        raise ValidationError(str(err)) from None


def log_identity(log: FlightLog, path: Path) -> dict[str, Any]:
    digest = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else ""
    return {"path": str(path), "format": log.fmt, "vehicle": log.vehicle, "duration_s": round(log.duration_s, 3),
            "sha256": digest, "warnings": list(log.warnings)}


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
        return {f"pwm_{k}_us": hold(log.signal(f"motor_{k}_pwm_us"), t_s) for k in range(1, 5)}
    if mapping is None:
        mapping = PwmMapping.from_ardupilot(log.params)
    u = mapped_inputs(WING_INPUTS, log, mapping, t_s)
    return {n: u[:, i] for i, n in enumerate(WING_INPUTS)}


def replay(host: FmuHost, log: FlightLog, log_path: Path, maps: Sequence[SignalMap], rate_hz: float = 50.0,
           window_s: float | None = 2.0, start_values: Mapping[str, float] | None = None,
           mapping: PwmMapping | None = None, t_range: tuple[float, float] | None = None,
           progress: Callable[[int, int], None] | None = None) -> ReplayResult:
    """Replay ``log`` through the FMU of ``host`` on a ``rate_hz`` grid and score the signals of ``maps``."""
    vehicle = vehicle_of(host)
    overrides = dict(start_values or {})
    unknown = [n for n in overrides if n not in host.variables]
    if unknown:
        raise ValidationError(f"--set: {', '.join(unknown)} not variables of {host.path.name}")
    missing_out = [m.fmu for m in maps if m.fmu not in host.variables]
    if missing_out:
        raise ValidationError(f"output map: {', '.join(missing_out)} not outputs of {host.path.name}")
    absent = [m.log for m in maps if not log.has(m.log)]
    motors = [f"motor_{k}_pwm_us" for k in range(1, 5)] if vehicle == "quadrotor" else []
    absent_in = [n for n in motors if not log.has(n)]
    if absent or absent_in:
        what = [f"inputs {', '.join(absent_in)}"] if absent_in else []
        what += [f"output-map signals {', '.join(absent)}"] if absent else []
        raise ValidationError(f"{log_path}: missing logged {'; '.join(what)}")
    first = log.signal("motor_1_pwm_us" if vehicle == "quadrotor" else "roll_rad")
    t0, t1 = (first.t_s[0], first.t_s[-1]) if t_range is None else t_range
    t = np.arange(t0, t1, 1.0 / rate_hz)
    if len(t) < 3:
        raise ValidationError(f"{log_path}: fewer than 3 samples at {rate_hz:g} Hz between {t0:g} and {t1:g} s")
    try:
        inputs = log_inputs(vehicle, log, t, mapping)
    except LogError as err:
        raise ValidationError(str(err)) from err
    params = {n: host.start_value(n) for n, v in host.variables.items() if v.causality == "parameter"}
    params.update(overrides)
    measured = {m.fmu: m.convert(resample_angle(log.signal(m.log), t) if m.wrap else log.signal(m.log).resample(t),
                                 host.unit(m.fmu), params) for m in maps}
    n = len(t)
    step = n - 1 if not window_s else max(1, round(window_s * rate_hz))
    edges = [*range(0, n - 1, step), n - 1]
    model = {m.fmu: np.full(n, np.nan) for m in maps}
    windows = []
    starts = initial_values_at(log, t[edges[:-1]], forward_from_airspeed=vehicle == "fixed_wing")
    for i, (a, b) in enumerate(itertools.pairwise(edges)):
        start = {**starts[i], **overrides}
        res = host.simulate(t[a:b + 1], {k: v[a:b + 1] for k, v in inputs.items()}, [m.fmu for m in maps], start)
        for m in maps:  # sample a is the re-initialisation itself: score the predicted samples a+1..b
            model[m.fmu][a + 1:b + 1] = m.align(res[m.fmu][1:], measured[m.fmu][a + 1:b + 1])
        windows.append((float(t[a]), float(t[b])))
        if progress:
            progress(i + 1, len(edges) - 1)
    keep = slice(1, n)
    overall = {m.fmu: fit_metrics(measured[m.fmu][keep], model[m.fmu][keep]) for m in maps}
    # each window scores its predicted samples a+1..b: in the kept series they start at a
    seg = {m.fmu: segment_metrics(measured[m.fmu][keep], model[m.fmu][keep], np.array(edges[:-1]))
           for m in maps}
    per_window = [{m.fmu: seg[m.fmu][i] for m in maps} for i in range(len(windows))]
    return ReplayResult(fmu_identity(host, overrides), log_identity(log, log_path), t[keep],
                        {k: v[keep] for k, v in model.items()}, {k: v[keep] for k, v in measured.items()},
                        windows, per_window, overall, tuple(maps), overrides)
