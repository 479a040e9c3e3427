"""Cost of validating one FMU on a 300 s log at 100 Hz: FMU stepping (FMPy's simulate_fmu loop and the FMU)
against our own overhead (reading the log, mapping inputs, initial states, metrics, report with plots).

Target: the validation overhead (read the log, map inputs, initial states, score against the
baselines, horizons, one-step check) below 25 % of the time spent stepping the FMU; printed as overhead /
stepping for the metrics-only run, and for the run that also draws the HTML report (matplotlib figures: a
separate, reported cost, the one part that does not scale with the FMU). Module imports (matplotlib, ~0.5 s)
are process start-up, paid once per batch, and happen before the clock starts. Each configuration runs
``--repeat`` times (the first report of the process pays the font loading once, as a batch worker does);
the median is shown. The log is a closed-loop flight of the quadrotor FMU, made (untimed) before the measurement.

Run: ``.venv/bin/python bench/validate.py [--seconds 300] [--rate 100] [--window 2]``; exit 1 when the
metrics-only ratio misses its target.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from build_fmus import build
from fmu_models.fmi import host as fmu_host
from identification.flights import synthetic
from identification.flights.scenarios import QuadrotorAutopilot, fly, published_thrust_inverse, quadrotor_profile
from identification.validation.replay import options
from identification.validation.workflow import ValidationJob, validate_job

TARGET_RATIO = 0.25  #: our overhead / FMU stepping time, metrics-only run


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=300.0)
    parser.add_argument("--rate", type=float, default=100.0)
    parser.add_argument("--window", type=float, default=2.0)
    parser.add_argument("--repeat", type=int, default=5, help="runs per configuration (median reported)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        fmu = build(None, d, ["quadrotor"])[0]
        ap = QuadrotorAutopilot(lambda t: quadrotor_profile(t % 50.0), published_thrust_inverse())
        rec = fly(fmu, ap, args.seconds, 1.0 / args.rate)
        log = synthetic.write_log(d / "flight.bin", rec, noise=True, seed=1)

        import identification.validation.report  # noqa: F401  (imports matplotlib: process start-up, paid once per batch)

        original = fmu_host.FmuHost.simulate
        runs = (("metrics only", None), ("with HTML report", str(d / "report")))
        figures: dict[str, list[tuple[float, float]]] = {label: [] for label, _ in runs}
        for _ in range(args.repeat):  # medians of several runs: this machine's timings scatter by +-20 %
            for label, report in runs:
                stepping = 0.0

                def timed(self: fmu_host.FmuHost, *a: object, **k: object) -> object:
                    nonlocal stepping
                    t0 = time.perf_counter()
                    try:
                        return original(self, *a, **k)
                    finally:
                        stepping += time.perf_counter() - t0

                fmu_host.FmuHost.simulate = timed  # type: ignore[method-assign]
                t0 = time.perf_counter()
                res = validate_job(ValidationJob(fmu, log, options(window_s=args.window, rate_hz=args.rate),
                                                 report_dir=Path(report) if report else None))
                figures[label].append((time.perf_counter() - t0, stepping))
                fmu_host.FmuHost.simulate = original  # type: ignore[method-assign]
    if res.status == "error":
        print(f"validation failed: {res.error}")
        return 1
    print(f"log: {args.seconds:.0f} s at {args.rate:.0f} Hz, windows of {args.window:g} s, "
          f"{len(res.signals)} signals, "
          f"{res.windows - res.excluded} of {res.windows} windows airborne")
    missed = False
    for label, samples in figures.items():
        ratios = [(tot - st) / st for tot, st in samples]
        total, stepping = samples[int(np.argsort(ratios)[len(ratios) // 2])]  # the run with the median ratio
        overhead = total - stepping
        print(f"{label:<17} total {total:.2f} s = FMU stepping {stepping:.2f} s + our overhead {overhead:.2f} s: "
              f"overhead / stepping {100 * overhead / stepping:.1f} % (median of {len(samples)}; all: "
              f"{', '.join(f'{100 * x:.0f}' for x in sorted(ratios))} %)"
              + ("; target < 25 %" if label == "metrics only" else "; figures included, no target"))
        missed |= label == "metrics only" and not overhead / stepping < TARGET_RATIO
    if missed:
        print(f"MISSED: validation overhead is not below {100 * TARGET_RATIO:.0f} % of the FMU stepping time")
    return 1 if missed else 0


if __name__ == "__main__":
    raise SystemExit(main())
