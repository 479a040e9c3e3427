"""Where ``bench/quadrotor_replica.py``'s kd_x errors come from: each replica flight with fresh accelerometer noise.

The replica study's drag errors are one draw of each flight's sensor noise. Here each draw's flight (the same
truth, closed loop, gyro noise and thus the same motor commands and velocities as in the study: its accelerometer
noise is drawn from the flight's generator but never fed back) is logged once with a noise-free accelerometer,
and ``identify quadrotor``'s drag regression (``drag_equation_error`` over its drag windows; x and y need no
thrust) is run on it:

- ``no accel noise``: the error left by the other logged noise (velocity 0.03 m/s, attitude 2 mrad);
- ``--reps`` fresh draws of white accelerometer noise (0.08 m/s2, the replica's): the mean error (the
  regression's expected error on that flight), the scatter over the printed std (1 when the std is right) and
  the 95 % coverage;
- ``study draw``: the study's own error on that flight and how many fresh-draw standard deviations it lies from
  that flight's expected error.

Printed per flight for kd_x and kd_y, then pooled. Exit 1 when the pooled coverage of either is below 90 % or
their expected errors differ by more than 3 standard errors (an estimator that treats x and y differently).

Run: ``.venv/bin/python bench/quadrotor_drag_noise.py [--draws 20] [--seed 0] [--reps 200]`` (10-30 s per flight).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import quadrotor_replica as study

import identification.flights.quadrotor_replica as replica
from identification.logs.flightlog import Signal
from identification.quadrotor import identify as q
from identification.quadrotor.segments import Segment

AXES = ("x", "y")


def flight_drag(seed: int, reps: int, rate_hz: float) -> dict[str, dict[str, float]]:
    """Per axis: truth, study-draw error, noise-free-accelerometer error, fresh-draw mean, std, mean printed std
    and coverage (relative errors)."""
    truth = replica.random_truth(np.random.default_rng(seed))
    blocks = replica.planned_blocks(sets=2)
    sim_hz = rate_hz * study.substeps(truth.tau_motor_s, rate_hz)
    drawn = replica.fly_replica(truth, blocks, rate_hz=rate_hz, sim_hz=sim_hz, seed=seed)
    noise_sd, replica.ACCEL_NOISE_M_S2 = replica.ACCEL_NOISE_M_S2, 0.0  # the same flight, accelerometer noise-free
    try:
        clean = replica.fly_replica(truth, blocks, rate_hz=rate_hz, sim_hz=sim_hz, seed=seed)
    finally:
        replica.ACCEL_NOISE_M_S2 = noise_sd
    segs = [Segment(b.start_s, b.end_s, b.axis) for b in blocks]
    fit_w, val_w = q._windows([clean.log], truth, q.QuadrotorOptions(segments=segs), [])
    windows = q._drag_windows([clean.log], truth, fit_w, val_w)

    def errors(log) -> dict[str, tuple[float, float]]:
        d = q.drag_equation_error([log], windows, truth, rate_hz=rate_hz)
        return {a: ((d[f"kd_{a}_N_s_m"]["value"] - getattr(truth, f"kd_{a}_N_s_m")) / getattr(truth, f"kd_{a}_N_s_m"),
                    d[f"kd_{a}_N_s_m"]["std"] / getattr(truth, f"kd_{a}_N_s_m")) for a in AXES}

    study_err, clean_err = errors(drawn.log), errors(clean.log)
    base = {a: clean.log.signals[f"accel_body_{a}_m_s2"] for a in AXES}
    rng = np.random.default_rng(10_000 + seed)
    fresh: dict[str, list[tuple[float, float]]] = {a: [] for a in AXES}
    for _ in range(reps):
        for s in base.values():
            clean.log.signals[s.name] = Signal(s.name, s.t_s, s.values + rng.normal(0.0, noise_sd, len(s.values)),
                                               s.unit, s.description)
        for a, v in errors(clean.log).items():
            fresh[a].append(v)
    out = {}
    for a in AXES:
        e, sd = np.array(fresh[a]).T
        out[a] = {"study": study_err[a][0], "clean": clean_err[a][0], "mean": float(e.mean()),
                  "scatter": float(e.std()), "printed": float(sd.mean()),
                  "coverage": float(np.mean(np.abs(e) <= 1.96 * sd))}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--reps", type=int, default=200)
    ap.add_argument("--rate-hz", type=float, default=250.0)
    args = ap.parse_args(argv)
    if not (1 <= args.draws <= 200 and 10 <= args.reps <= 2000):
        ap.error("--draws must lie in 1..200 and --reps in 10..2000")
    rows = []
    for d in range(args.draws):
        r = flight_drag(args.seed + d, args.reps, args.rate_hz)
        rows.append(r)
        print(f"flight {args.seed + d:3d}: " + "  |  ".join(
            f"kd_{a}: study {100 * r[a]['study']:+6.2f} %, no accel noise {100 * r[a]['clean']:+6.2f} %, fresh "
            f"mean {100 * r[a]['mean']:+6.2f} %, scatter/printed {r[a]['scatter'] / r[a]['printed']:.2f}, coverage "
            f"{100 * r[a]['coverage']:3.0f} %, study draw {(r[a]['study'] - r[a]['mean']) / r[a]['scatter']:+5.2f} sd"
            for a in AXES), flush=True)
    failed = False
    expected = {}
    for a in AXES:
        mean = np.array([r[a]["mean"] for r in rows])
        z = np.array([(r[a]["study"] - r[a]["mean"]) / r[a]["scatter"] for r in rows])
        cov = float(np.mean([r[a]["coverage"] for r in rows]))
        ratio = float(np.mean([r[a]["scatter"] / r[a]["printed"] for r in rows]))
        expected[a] = (float(mean.mean()), float(mean.std(ddof=1) / math.sqrt(len(mean))) if len(mean) > 1 else 0.0)
        study_mean = float(np.mean([r[a]["study"] for r in rows]))
        print(f"kd_{a}: study mean error {100 * study_mean:+.2f} %; expected (fresh-draw means) "
              f"{100 * expected[a][0]:+.2f} % +- {100 * expected[a][1]:.2f} %; no accel noise "
              f"{100 * np.mean([r[a]['clean'] for r in rows]):+.2f} %; scatter/printed {ratio:.2f}; fresh coverage "
              f"{100 * cov:.1f} %; study draws {z.mean():+.2f} +- {z.std(ddof=1) if len(z) > 1 else 0.0:.2f} sd "
              f"(mean +- scatter), {int(np.sum(np.abs(z) > 1.96))} beyond 1.96")
        failed |= cov < 0.90
    diff = abs(expected["x"][0] - expected["y"][0])
    se = math.hypot(expected["x"][1], expected["y"][1])
    failed |= diff > 3.0 * se
    print(f"kd_x - kd_y expected error {100 * (expected['x'][0] - expected['y'][0]):+.2f} % (+- {100 * se:.2f} %): "
          f"{'the regression treats x and y differently' if diff > 3.0 * se else 'alike within 3 standard errors'}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
