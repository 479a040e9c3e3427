"""Replay recorded inputs through an FMU with FMPy and score its outputs against the record.

Nothing of the Python model is imported: the FMU is driven through FMPy's FMU2Slave exactly as any FMI
importer would (``uavfmu.scenarios.FmuRunner``). Supports a full-length replay and segment-wise replay
(windows re-initialised from the recorded state), the usual way open-loop-unstable vehicles are judged.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from identification.metrics import FitMetrics, fit_metrics
from uavfmu.scenarios import FmuRunner

#: FMU start parameter <- recorded output used to re-initialise a window (names of docs/interfaces.md)
INIT_FROM_OUTPUTS = {
    "init_pos_north_m": "pos_north_m", "init_pos_east_m": "pos_east_m", "init_pos_down_m": "pos_down_m",
    "init_vel_body_x_m_s": "vel_body_x_m_s", "init_vel_body_y_m_s": "vel_body_y_m_s",
    "init_vel_body_z_m_s": "vel_body_z_m_s", "init_roll_rad": "roll_rad", "init_pitch_rad": "pitch_rad",
    "init_yaw_rad": "yaw_rad", "init_rate_body_x_rad_s": "rate_body_x_rad_s",
    "init_rate_body_y_rad_s": "rate_body_y_rad_s", "init_rate_body_z_rad_s": "rate_body_z_rad_s",
}


class ValidationError(ValueError):
    """Inputs or signals missing or mismatched; the message names what."""


@dataclass
class WindowResult:
    t0_s: float
    t1_s: float
    model: dict[str, np.ndarray]
    metrics: dict[str, FitMetrics]


@dataclass
class ValidationResult:
    fmu: str
    windows: list[WindowResult] = field(default_factory=list)

    def overall(self, signal: str) -> FitMetrics:
        """Metrics of one signal over all windows together."""
        meas = np.concatenate([w.model[f"_measured_{signal}"] for w in self.windows])
        mod = np.concatenate([w.model[signal] for w in self.windows])
        return fit_metrics(meas, mod)


def replay(fmu: Path, t_s: np.ndarray, inputs: Mapping[str, np.ndarray], measured: Mapping[str, np.ndarray],
           signals: list[str], window_s: float | None = None, start_values: Mapping[str, float] | None = None,
           ) -> ValidationResult:
    """Replay ``inputs`` (sampled at ``t_s``, held over each interval) and score ``signals``.

    ``measured`` holds the recorded signals at ``t_s`` (FMU output names); each window starts from the
    recorded state at its first sample (``INIT_FROM_OUTPUTS``), so ``measured`` must contain those too.
    """
    t_s = np.asarray(t_s, dtype=float)
    missing = [n for n in list(INIT_FROM_OUTPUTS.values()) + signals if n not in measured]
    if missing:
        raise ValidationError(f"recorded signal(s) missing: {', '.join(sorted(set(missing)))}")
    for name, v in list(inputs.items()) + list(measured.items()):
        if len(v) != len(t_s):
            raise ValidationError(f"{name} has {len(v)} samples, time has {len(t_s)}")
    dt = np.diff(t_s)
    if np.any(dt <= 0):
        raise ValidationError("time must increase strictly")
    n = len(t_s)
    edges = [0, n - 1] if window_s is None else [*list(range(0, n - 1, max(1, round(window_s / dt.mean())))), n - 1]
    result = ValidationResult(str(fmu))
    for a, b in itertools.pairwise(edges):
        start = dict(start_values or {})
        start.update({p: float(measured[o][a]) for p, o in INIT_FROM_OUTPUTS.items()})
        model = {s: np.empty(b - a + 1) for s in signals}
        with FmuRunner(fmu, start) as run:
            y = run.read()
            for s in signals:
                model[s][0] = y[s]
            for k in range(a, b):
                y = run.step(t_s[k] - t_s[a], t_s[k + 1] - t_s[k], {n_: float(v[k]) for n_, v in inputs.items()})
                for s in signals:
                    model[s][k - a + 1] = y[s]
        metrics = {s: fit_metrics(measured[s][a:b + 1], model[s]) for s in signals}
        for s in signals:
            model[f"_measured_{s}"] = np.asarray(measured[s][a:b + 1], dtype=float)
        result.windows.append(WindowResult(float(t_s[a]), float(t_s[b]), model, metrics))
    return result
