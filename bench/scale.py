"""Scale-out of batch validation and Monte Carlo replays on ``identification.common.parallel`` (dask.distributed).

1. Batch: ``--pairs`` native fixed-wing FMU x log pairs (``--seconds`` s noisy logs, 2 s windows, metrics only)
   on a local cluster of 1 and of 2 worker processes; pairs per second each and the scaling efficiency
   (rate at 2 workers / (2 x rate at 1 worker)). Target: >= 80 % at 2 workers.
2. Monte Carlo: ``--draws`` draws of one replay on 1 worker, against the bare FMU stepping time of the same
   draws (``simulate_fmu`` over every window, in this process, no dask). Target: MC time <= 1.25 x bare.

Cluster start-up (worker processes, imports) is paid before the clocks start and printed apart; each
configuration runs ``--repeat`` times (1 and 2 workers alternating; Monte Carlo and bare stepping alternating)
and the best time counts (timings on a shared machine scatter, and the least disturbed run is the closest to
the cost of the work).
The machine's load average is printed beside: efficiency needs two idle cores. Exit 1 when a target is missed.

Run: ``.venv/bin/python bench/scale.py [--pairs 16] [--seconds 20] [--draws 40] [--repeat 3] [--parts batch,mc]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from build_fmus import build
from fmu_models.common.params import Uncertainty
from fmu_models.fmi.host import FmuHost
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.common.parallel import Executor
from identification.flights import synthetic
from identification.logs.readers import read_log
from identification.validation import mc_bands, output_map
from identification.validation.replay import options, replay_setup, simulate_setup
from identification.validation.workflow import ValidationJob, validate, validate_batch

EFFICIENCY_TARGET = 0.80
MC_TARGET = 1.25
NAMES = ["C_ell_p", "C_m_q", "C_n_r", "C_m_alpha"]
MEAN = [-0.51, -38.21, -0.095, -2.74]


def make_logs(d: Path, pairs: int, seconds: float) -> list[Path]:
    """One noiseless flight, ``pairs`` sensor-noise seeds (the logs differ, the cost per pair does not)."""
    t, sig = synthetic.fixed_wing_flight(seconds=seconds, rate_hz=50.0)
    logs = []
    for k in range(pairs):
        logs.append(synthetic.write_csv_log(d / f"wing{k:03d}.csv", t, synthetic.with_noise(sig, k)))
    return logs


def batch_rates(jobs: list[ValidationJob], repeat: int) -> tuple[float, float, float, float]:
    """Pairs per second on 1 and on 2 local worker processes, and each cluster's start-up [s]; both clusters
    open at once (an idle one costs nothing) and their runs alternating, so that both see the same load."""
    t0 = time.perf_counter()
    with Executor(workers=1) as one:
        validate_batch(jobs[:1], executor=one)  # warm-up: worker imports, FMU cache
        up1 = time.perf_counter() - t0
        t0 = time.perf_counter()
        with Executor(workers=2) as two:
            validate_batch(jobs[:2], executor=two)
            up2 = time.perf_counter() - t0
            best = {1: float("inf"), 2: float("inf")}
            for _ in range(repeat):
                for n, ex in ((1, one), (2, two)):
                    t1 = time.perf_counter()
                    res = validate_batch(jobs, executor=ex)
                    best[n] = min(best[n], time.perf_counter() - t1)
                    errors = [r.error for r in res if r.status == "error"]
                    if errors:
                        raise SystemExit(f"bench/scale.py: batch errors: {errors[:2]}")
    return len(jobs) / best[1], len(jobs) / best[2], up1, up2


def bare_stepping_s(job: ValidationJob, unc: Uncertainty, draws: int) -> float:
    """Seconds to step the FMU through every scored window for ``draws`` parameter sets, in this process."""
    log = read_log(job.log)
    with FmuHost(job.fmu) as host:
        maps = output_map.load(None, "fixed_wing")
        setup = replay_setup(host, log, job.log, maps, job.options, {}, PwmMapping.load(job.mapping))
        rng = np.random.default_rng(0)
        std = np.sqrt(np.diag(unc.covariance))
        t0 = time.perf_counter()
        for _ in range(draws):
            params = dict(zip(unc.names, (np.asarray(unc.mean) + std * rng.standard_normal(len(std))).tolist(),
                              strict=True))
            simulate_setup(host, setup, maps, [{**s, **params} for s in setup.starts])  # a draw's FMU calls
        return time.perf_counter() - t0


def mc_against_bare(job: ValidationJob, unc: Uncertainty, draws: int, repeat: int) -> tuple[float, float]:
    """(Monte Carlo seconds for ``draws`` draws on one worker, bare stepping seconds of as many draws), each the
    best of ``repeat`` runs, the two alternating so that both see the same load of the machine."""
    nominal = validate(job)
    res = nominal.replay
    assert res is not None
    log = read_log(job.log)
    with FmuHost(job.fmu) as host:
        units = {n: host.unit(n) for n in host.variables}
    mc, bare = float("inf"), float("inf")
    with Executor(workers=1) as ex:
        mc_bands.monte_carlo(job, unc, res, log, mc_bands.MIN_DRAWS, 0, ex, units)  # warm-up
        for _ in range(repeat):
            bare = min(bare, bare_stepping_s(job, unc, draws))
            t0 = time.perf_counter()
            mc_bands.monte_carlo(job, unc, res, log, draws, 0, ex, units)
            mc = min(mc, time.perf_counter() - t0)
    return mc, bare


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--draws", type=int, default=40)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--parts", default="batch,mc", help="which measurements: batch, mc or both")
    args = parser.parse_args()
    parts = set(args.parts.split(","))
    if not parts or not parts <= {"batch", "mc"}:
        parser.error(f"--parts = {args.parts!r}: allowed a comma-separated subset of batch, mc")
    checks = []
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        fmu = build(None, d, ["fixed_wing"])[0]
        mapping = synthetic.write_mapping_toml(d / "mapping.toml")
        logs = make_logs(d, args.pairs, args.seconds)
        opts = options(window_s=2.0, rate_hz=50.0)
        jobs = [ValidationJob(fmu, log, opts, mapping=mapping) for log in logs]
        load0 = os.getloadavg()[0]
        if "batch" in parts:
            rate1, rate2, up1, up2 = batch_rates(jobs, args.repeat)
            eff = rate2 / (2.0 * rate1)
            print(f"batch: {args.pairs} pairs of {args.seconds:g} s logs, native fixed-wing FMU, 2 s windows, "
                  "metrics only")
            print(f"  1 worker : {rate1:6.2f} pairs/s   (cluster start-up {up1:.1f} s, not timed)")
            print(f"  2 workers: {rate2:6.2f} pairs/s   (cluster start-up {up2:.1f} s, not timed)")
            print(f"  scaling efficiency at 2 workers: {eff:.0%} (target >= {EFFICIENCY_TARGET:.0%})")
            checks.append(("scaling efficiency", eff < EFFICIENCY_TARGET))
        if "mc" in parts:
            unc = Uncertainty(names=NAMES, mean=MEAN, covariance=np.diag((0.01 * np.abs(MEAN)) ** 2).tolist())
            mc, bare = mc_against_bare(jobs[0], unc, args.draws, args.repeat)
            ratio = mc / bare
            print(f"Monte Carlo: {args.draws} draws of a {args.seconds:g} s log on 1 worker {mc:.2f} s; bare FMU "
                  f"stepping of the same draws {bare:.2f} s; ratio {ratio:.2f} (target <= {MC_TARGET:g})")
            checks.append(("Monte Carlo ratio", ratio > MC_TARGET))
        load1 = os.getloadavg()[0]
    print(f"machine: {os.cpu_count()} cores, load average {load0:.1f} before / {load1:.1f} after (other processes "
          "share the cores: efficiency needs 2 idle ones)")
    missed = [what for what, bad in checks if bad]
    print("MISSED: " + ", ".join(missed) if missed else "targets met")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
