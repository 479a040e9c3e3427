"""Benchmark: `identify thrust` on the three Erle flights of ../shared/data, every phase timed.

Phases: read (log parsing), align (airborne cut, lag search, accelerometer averaging), cross-validation
(train + score of every leave-one-flight-out fold, baselines included), final fit, and the whole
``identify_thrust`` call end to end. The reference measured in the same run is the read phase alone
(the floor any tool pays); the goal (issue 13) is < 10 s end to end on the CI machine. Median of
``REPEATS`` runs.

    .venv/bin/python bench/identify_thrust.py
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from identification.readers import read_log
from identification.thrust_dataset import ThrustDatasetConfig, build_thrust_dataset
from identification.thrust_workflow import (
    FlightSpec,
    ThrustConfig,
    fit_model,
    folds,
    identify_thrust,
    load_flight,
    model_spec,
    score_fold,
)

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "quadrotor"
LOGS = ("arducopter_x_quad_real_218.BIN", "arducopter_x_quad_real_104.BIN", "arducopter_x_quad_real_105.BIN")
GOAL_S = 10.0
REPEATS = 3


def phases(cfg: ThrustConfig) -> dict[str, float]:
    """Wall time [s] of each phase, run one after the other as identify_thrust does."""
    t: dict[str, float] = {}
    t0 = time.perf_counter()
    logs = [read_log(f.path) for f in cfg.flights]
    t["read"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    for f, log in zip(cfg.flights, logs, strict=True):
        build_thrust_dataset(log, ThrustDatasetConfig(mass_kg=f.mass_kg, airborne_on_mean_pwm=True))
    t["align"] = time.perf_counter() - t0
    flights = [load_flight(f, cfg) for f in cfg.flights]
    spec, _ = model_spec(flights, cfg)
    t0 = time.perf_counter()
    for name, train, test in folds(flights, cfg.n_folds_single):
        score_fold(name, train, test, spec, cfg, calibrate=True)
    t["cross-validation (train + score)"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    fit_model(flights, spec, cfg, source="bench")
    t["final fit"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    identify_thrust(cfg)
    t["identify_thrust end to end"] = time.perf_counter() - t0
    return t


def main() -> int:
    paths = [DATA / n for n in LOGS]
    if not all(p.exists() for p in paths):
        print(f"bench/identify_thrust.py: needs {DATA} (../shared/data beside the checkout)")
        return 2
    cfg = ThrustConfig(flights=tuple(FlightSpec(p, 1.14) for p in paths), calibrate="on")
    runs = [phases(cfg) for _ in range(REPEATS)]
    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    print(f"identify thrust, {len(paths)} Erle logs, median of {REPEATS} runs")
    for k, v in med.items():
        print(f"  {k:<34} {v:7.3f} s")
    total = med["identify_thrust end to end"]
    print(f"end to end / read alone (reference, same run): {total / med['read']:.2f}x")
    print(f"end to end / goal {GOAL_S:.0f} s: {total / GOAL_S:.3f} ({'met' if total < GOAL_S else 'NOT met'})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
