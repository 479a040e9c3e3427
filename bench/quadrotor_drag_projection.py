"""Is ``bench/quadrotor_replica.py``'s accelerometer noise independent of the flights' velocity?

The drag regression's error along body x is, to first order, the accelerometer noise projected onto the body
velocity. Per replica flight (seeds as the replica study's) this script flies the flight with a noise-free
accelerometer, and once more without gyro noise, rebuilds the flight's own accelerometer noise from its generator
(the replica draws gyro, accelerometer, attitude and velocity noise in that order each sample), and prints:

- the projection ``z = v . n / |v|`` of the unit noise ``n`` onto the centred body velocity ``v`` along x and y
  (standard normal when the noise is independent of the velocity);
- how much of ``v_x`` the gyro noise makes (rms of the difference to the flight without it).

Exit 1 when the projections' mean over the flights lies more than 3 standard errors from 0 or their std outside
0.7-1.4 on either axis (noise that depends on the flight).

Run: ``.venv/bin/python bench/quadrotor_drag_projection.py [--seeds 0-19,100-119]`` (about 15 s per flight).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import quadrotor_replica as study

import identification.flights.quadrotor_replica as replica
from identification.quadrotor import identify as q


def seeds_of(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def flight_velocity(seed: int, gyro_noise: bool, rate_hz: float = 250.0) -> tuple[np.ndarray, int]:
    """Centred body velocity (x, y) of the replica flight ``seed`` with a noise-free accelerometer (and without
    gyro noise unless ``gyro_noise``), and its sample count."""
    truth = replica.random_truth(np.random.default_rng(seed))
    saved = replica.ACCEL_NOISE_M_S2, replica.GYRO_NOISE_RAD_S
    replica.ACCEL_NOISE_M_S2 = 0.0
    replica.GYRO_NOISE_RAD_S = saved[1] if gyro_noise else 0.0
    try:
        f = replica.fly_replica(truth, replica.planned_blocks(sets=2), rate_hz=rate_hz,
                                sim_hz=rate_hz * study.substeps(truth.tau_motor_s, rate_hz), seed=seed)
    finally:
        replica.ACCEL_NOISE_M_S2, replica.GYRO_NOISE_RAD_S = saved
    t = f.log.signal("accel_body_x_m_s2").t_s
    v = q._body_velocity(f.log, t)[:, :2]
    return v - v.mean(axis=0), len(t)


def accel_noise(seed: int, n: int) -> np.ndarray:
    """The flight's unit accelerometer noise (n x 3), drawn from its generator as ``fly_replica`` draws it."""
    rng = np.random.default_rng(seed)
    rng.uniform(-1.0, 1.0, 3)  # accelerometer bias
    rng.uniform(-1.0, 1.0, 3)  # gyro bias
    out = np.empty((n, 3))
    for k in range(n):
        rng.normal(0.0, 1.0, 3)  # gyro
        out[k] = rng.normal(0.0, 1.0, 3)
        for _ in range(6):  # attitude, velocity
            rng.normal(0.0, 1.0)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-19,100-119")
    args = ap.parse_args(argv)
    seeds = seeds_of(args.seeds)
    if not 1 <= len(seeds) <= 400:
        ap.error("--seeds must name 1..400 flights")
    z = []
    for s in seeds:
        v, n = flight_velocity(s, True)
        v0, _ = flight_velocity(s, False)
        noise = accel_noise(s, n)
        zs = [float(v[:, i] @ noise[:, i] / math.sqrt(v[:, i] @ v[:, i])) for i in range(2)]
        z.append(zs)
        print(f"flight {s:4d}: z_x {zs[0]:+.2f}  z_y {zs[1]:+.2f}  v_x rms {math.sqrt(np.mean(v[:, 0] ** 2)):.3f} "
              f"m/s, of it from gyro noise {math.sqrt(np.mean((v[:, 0] - v0[:, 0]) ** 2)):.4f} m/s", flush=True)
    arr = np.array(z)
    bad = False
    for i, a in enumerate("xy"):
        mean, sd = float(arr[:, i].mean()), float(arr[:, i].std(ddof=1)) if len(arr) > 1 else float("nan")
        se = sd / math.sqrt(len(arr))
        off = abs(mean) > 3 * se or not 0.7 <= sd <= 1.4
        bad |= off
        print(f"{a}: projections mean {mean:+.2f} (+- {se:.2f}), std {sd:.2f} over {len(arr)} flights"
              f"{'  DEPENDENT' if off else ''}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
