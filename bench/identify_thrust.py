"""Benchmark: `identify thrust` on the shared flights: speed on the three Erle logs, and the held-out targets.

Speed: the three Erle flights end to end under ``GOAL_S`` on the CI machine; phases timed (read,
align, nested cross-validation, final fit); the reference measured in the same run is the read phase alone
(the floor any tool pays). Median of ``REPEATS`` runs.

Accuracy, leave-one-flight-out on the three Erle flights (no voltage) and on the two PX4 flights
(voltage, masses 1.32 / 1.085 kg, FMU mass 1.2 kg), both with the per-flight hover calibration on: the
model's pooled RMSE over the best baseline's given the same side information (ratio measured in the same run)
at most ``MAX_RATIO`` at every information level (none, hover battery state, per-flight calibration), and no
baseline beating the model (skill interval) on any held-out flight. Prints the LOFO table.

    .venv/bin/python bench/identify_thrust.py          # exit 1 when a target is missed
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from identification.logs.readers import read_log
from identification.thrust.dataset import ThrustDatasetConfig, build_thrust_dataset
from identification.thrust.model import fit_physical
from identification.thrust.workflow import (
    FlightSpec,
    ThrustConfig,
    ThrustResult,
    _select,
    base_spec,
    identify_thrust,
    load_flight,
    outer_folds,
    score_fold,
)

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
ERLE = tuple(DATA / "quadrotor" / f"arducopter_x_quad_real_{n}.BIN" for n in (218, 104, 105))
PX4 = ((DATA / "quadrotor_px4_csv" / "drone1-8", 1.32), (DATA / "quadrotor_px4_csv" / "drone1-10", 1.085))
GOAL_S = 10.0
MAX_RATIO = 0.95
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
    base, _ = base_spec(flights, cfg)
    data = [f.model_data(base.voltage) for f in flights]
    t0 = time.perf_counter()
    for name, train, test in outer_folds(data, cfg.n_folds_single):
        score_fold(name, train, test, base, cfg, calibrate=True)
    t["nested cross-validation + scores"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    fit_physical(data, _select(data, base, cfg, True), cfg.epochs, cfg.check_block_s, "bench")
    t["final selection + fit"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    identify_thrust(cfg)
    t["identify_thrust end to end"] = time.perf_counter() - t0
    return t


def speed() -> bool:
    cfg = ThrustConfig(flights=tuple(FlightSpec(p, 1.14) for p in ERLE), calibrate="on")
    runs = [phases(cfg) for _ in range(REPEATS)]
    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    print(f"identify thrust, {len(ERLE)} Erle logs, median of {REPEATS} runs")
    for k, v in med.items():
        print(f"  {k:<34} {v:7.3f} s")
    total = med["identify_thrust end to end"]
    print(f"end to end / read alone (reference, same run): {total / med['read']:.2f}x")
    ok = total < GOAL_S
    print(f"end to end / goal {GOAL_S:.0f} s: {total / GOAL_S:.3f} ({'met' if ok else 'NOT met'})")
    return ok


def lofo_table(r: ThrustResult) -> list[str]:
    """Model vs constant vs polynomial per held-out flight, raw and calibrated (RMSE [N])."""
    cols = [k for k in r.pooled if k.startswith(("model", "constant", "poly"))]
    head = ["held-out", *cols]
    rows = [[f.held_out, *(f"{({'model': f.model, **f.baselines})[c].rmse_N:.3f}" for c in cols)] for f in r.folds]
    rows.append(["pooled", *(f"{r.pooled[c]:.3f}" for c in cols)])
    widths = [max(len(x[i]) for x in [head, *rows]) for i in range(len(head))]
    return ["  " + " | ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)) for row in [head, *rows]]


def accuracy(name: str, cfg: ThrustConfig) -> bool:
    r = identify_thrust(cfg)
    print(f"\n{name}: leave-one-flight-out, model = {r.spec.describe()}")
    print("\n".join(lofo_table(r)))
    ok = True
    for column in dict.fromkeys(c["information"] for c in r.comparisons.values()):
        comps = {k: c for k, c in r.comparisons.items() if c["information"] == column}
        worst = max(comps.values(), key=lambda c: c["rmse_ratio"])
        losses = [f"{c['baseline']} on {h}" for c in comps.values() for h, o in c["per_held_out"].items()
                  if o["outcome"] == "lose"]
        met = worst["rmse_ratio"] <= MAX_RATIO and not losses
        ok &= met
        tag = column if worst["in_verdict"] else f"{column}, not in the verdict"
        print(f"  [{tag}] pooled RMSE {worst['model']} / best baseline ({worst['baseline']}) = "
              f"{worst['rmse_ratio']:.3f} (target <= {MAX_RATIO}); loses on: {', '.join(losses) or 'none'} -> "
              f"{'met' if met else 'NOT met'}")
    return ok


def main() -> int:
    needed = [*ERLE, *(p for p, _ in PX4)]
    if not all(p.exists() for p in needed):
        print(f"bench/identify_thrust.py: needs {DATA} (../shared/data beside the checkout)")
        return 2
    ok = speed()
    ok &= accuracy("Erle (no voltage)", ThrustConfig(flights=tuple(FlightSpec(p, 1.14) for p in ERLE), calibrate="on"))
    ok &= accuracy("PX4 (voltage)", ThrustConfig(flights=tuple(FlightSpec(p, m) for p, m in PX4), calibrate="on",
                                                 fmu_mass_kg=1.2))
    print(f"\nall targets: {'met' if ok else 'NOT met'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
