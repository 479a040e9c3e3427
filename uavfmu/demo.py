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
    in_band = {f"pwm_{i}_us": 1520.0 for i in range(1, 5)}
    g = simulate_fmu(str(fmu), stop_time=0.01, start_values={"init_pos_down_m": -10.0, **in_band},
                     output=["gravity_m_s2"])["gravity_m_s2"][0]
    pwm = brentq(lambda x: amap.evaluate([np.array([x])])[0] - 1.14 * g, 6000.0, 6217.3) / 4
    res = simulate_fmu(str(fmu), stop_time=10.0, output_interval=0.01,
                       start_values={"init_pos_down_m": -10.0, **{f"pwm_{i}_us": pwm for i in range(1, 5)}},
                       output=["altitude_m", "accel_body_z_m_s2"])
    return {"hover PWM [us]": pwm, "max |altitude - 10 m| [mm]": 1e3 * float(np.max(np.abs(res["altitude_m"] - 10))),
            "accel z [m/s2]": float(res["accel_body_z_m_s2"][-1])}


def fly_fixed_wing(fmu: Path) -> dict[str, float]:
    """Trim at 25 m/s (uavbook method), fly 20 s from the trim through FMPy, then roll with the aileron."""
    from fmpy import simulate_fmu

    from fmu_models.common.rigid_body import euler_from_quat
    from fmu_models.common.simulate import Simulator
    from fmu_models.fixed_wing.model import FixedWingModel
    from fmu_models.fixed_wing.trim import trim

    sim = Simulator(FixedWingModel())
    p = sim.params()
    t = trim(sim.model, p, 25.0)
    pitch = float(np.asarray(euler_from_quat(t.x[6:10])).ravel()[1])
    start = {"init_pos_down_m": -100.0, "init_vel_body_x_m_s": float(t.x[3]), "init_vel_body_z_m_s": float(t.x[5]),
             "init_pitch_rad": pitch, "aileron_rad": float(t.u[0]), "elevator_rad": float(t.u[1]),
             "rudder_rad": float(t.u[2]), "throttle": float(t.u[3])}
    res = simulate_fmu(str(fmu), stop_time=20.0, output_interval=0.01, start_values=start,
                       output=["airspeed_m_s", "altitude_m", "roll_rad"])
    return {"trim alpha [deg]": np.degrees(t.alpha_rad), "trim elevator [deg]": np.degrees(t.elevator_rad),
            "trim throttle [-]": t.throttle,
            "max |Va - 25| over 20 s [m/s]": float(np.max(np.abs(res["airspeed_m_s"] - 25))),
            "max |altitude - 100| [m]": float(np.max(np.abs(res["altitude_m"] - 100)))}


def run(args: argparse.Namespace) -> int:
    from build_fmus import build

    t0 = time.perf_counter()
    paths = {p.stem: p for p in build(None, args.out)}
    print(f"built {', '.join(str(p) for p in paths.values())} in {time.perf_counter() - t0:.1f} s")
    rows = fly_quadrotor(paths["quadrotor"])
    print("\nquadrotor.fmu, hover (paper 000 published ANFIS map, DJI F450)")
    for k, v in rows.items():
        print(f"  {k:<34} {v:10.4f}")
    rows = fly_fixed_wing(paths["fixed_wing"])
    print("\nfixed_wing.fmu, wings-level trim at 25 m/s (Aerosonde, Beard & McLain)")
    for k, v in rows.items():
        print(f"  {k:<34} {v:10.4f}")
    return 0
