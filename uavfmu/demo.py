"""`uavfmu demo`: build both FMUs with the papers' parameters and fly them through FMPy; print a summary."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=Path("dist"), help="where the FMUs go (default: dist)")
    parser.add_argument("--real", action="store_true", help="also use the real logs in ../shared/data")


def fly_quadrotor(fmu: Path) -> dict[str, float]:
    """Hover at the published map's hover PWM from 10 m for 10 s; return the height excursion."""
    from fmpy import simulate_fmu
    from scipy.optimize import brentq

    from fmu_models.quadrotor.anfis import published_map

    amap = published_map()
    g = simulate_fmu(str(fmu), stop_time=0.01, output=["gravity_m_s2"])["gravity_m_s2"][0]
    pwm = brentq(lambda x: amap.evaluate([np.array([x])])[0] - 1.14 * g, 6000.0, 6217.3) / 4
    res = simulate_fmu(str(fmu), stop_time=10.0, output_interval=0.01,
                       start_values={"init_pos_down_m": -10.0, **{f"pwm_{i}_us": pwm for i in range(1, 5)}},
                       output=["altitude_m", "accel_body_z_m_s2"])
    return {"hover PWM [us]": pwm, "max |altitude - 10 m| [mm]": 1e3 * float(np.max(np.abs(res["altitude_m"] - 10))),
            "accel z [m/s2]": float(res["accel_body_z_m_s2"][-1])}


def run(args: argparse.Namespace) -> int:
    from build_fmus import build

    t0 = time.perf_counter()
    paths = {p.stem: p for p in build(None, args.out)}
    print(f"built {', '.join(str(p) for p in paths.values())} in {time.perf_counter() - t0:.1f} s")
    rows = fly_quadrotor(paths["quadrotor"])
    print("\nquadrotor.fmu, hover (paper 000 published ANFIS map, DJI F450)")
    for k, v in rows.items():
        print(f"  {k:<30} {v:10.4f}")
    return 0
