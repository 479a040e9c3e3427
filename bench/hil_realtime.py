"""Lockstep pacing over 30 s: at ``--speed 1`` simulation time must advance within 2 % of the wall time for the
PX4 interface (a fake lockstep PX4 over TCP) and the ArduPilot JSON interface (a fake SITL over UDP at 250 Hz),
both on the quadrotor FMU; ``max`` (unpaced) is measured in the same run for reference. Prints the ratio
simulation seconds / wall seconds per interface and exits 1 when a speed-1 run misses 1 +- 0.02.

Run: ``.venv/bin/python bench/hil_realtime.py [--seconds 30]`` (the tests run the same loops for 3 s).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from build_fmus import build
from tests.fakes.hil import json_pace, px4_pace

TOLERANCE = 0.02  #: allowed |simulation / wall - 1| at speed 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=30.0, help="wall time per paced run (1..600 s)")
    args = ap.parse_args(argv)
    if not 1.0 <= args.seconds <= 600.0:
        ap.error(f"--seconds {args.seconds}; allowed 1..600")
    with tempfile.TemporaryDirectory() as tmp:
        (fmu,) = build(None, Path(tmp), only=["quadrotor"])
        misses = 0
        for name, run in (("px4", px4_pace), ("ardupilot-json", json_pace)):
            sim, wall, stats = run(fmu, 1.0, args.seconds)
            ratio = sim / wall
            ok = abs(ratio - 1.0) <= TOLERANCE
            misses += not ok
            sim_max, wall_max, _ = run(fmu, None, min(args.seconds, 5.0))
            print(f"{name}: speed 1: {sim:.3f} s simulated in {wall:.3f} s of wall time, ratio {ratio:.4f} "
                  f"(target 1 +- {TOLERANCE}) {'ok' if ok else 'MISS'}; summary real_time_factor "
                  f"{stats.real_time_factor:.4f}, overruns {stats.overruns}; speed max: {sim_max / wall_max:.2f}x",
                  flush=True)
    return 1 if misses else 0


if __name__ == "__main__":
    sys.exit(main())
