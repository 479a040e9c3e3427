"""Study: would a yaw-rate damping term make the quadrotor's yaw replay physical, or only beat persistence?

The FMU's yaw axis is ``Jz dr/dt = -(b/k) sum_i s_i T_i``; ``identify thrust`` fits ``c = b/k`` by output error
over 2 s windows of the logged PWM and scores it, leave-one-flight-out, against holding the logged yaw rate.
Here the same windows (Erle 218/104/105, PX4 drone1-8/drone1-10) are replayed by three models fitted on the
other flights: ``c`` alone (the FMU), ``c`` with a damping ``-kd r``, and the damping alone (``c = 0``: the
motors play no part). ``kd`` is a grid search, ``c`` least squares (the replay is linear in it). Printed: the
held-out skill against holding the rate with its 90 % block-bootstrap interval, the fitted ``kd / Jz``, and
the rotor damping that momentum theory gives, ``8 b Omega_hover / Jz`` (each rotor's drag torque ``b Omega^2``
changes by ``2 b Omega r`` when the body yaws at ``r``). A study, not a target: exit 0 when the data are
there, 2 when not.

    .venv/bin/python bench/yaw_damping_study.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy import signal

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.params import QuadrotorParams
from identification.common.metrics import skill_interval
from identification.thrust.model import battery_input_V, fmu_total_thrust
from identification.thrust.workflow import FlightSpec, ThrustConfig, identify_thrust, load_flight, yaw_windows

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
ERLE = tuple(FlightSpec(DATA / "quadrotor" / f"arducopter_x_quad_real_{n}.BIN", 1.14) for n in (218, 104, 105))
PX4 = (FlightSpec(DATA / "quadrotor_px4_csv" / "drone1-8", 1.32),
       FlightSpec(DATA / "quadrotor_px4_csv" / "drone1-10", 1.085))
B_DEFAULT = QuadrotorParams().b_drag_N_m_s2
KD_PER_JZ_1_S = (0.0, 0.1, 0.3, 1.0, 2.0, 3.0, 5.0, 10.0)


def replay(ms: list, c_m: float, kd_per_jz: float, jz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Replayed and logged yaw rate [rad/s] of ``Jz dr/dt = -c u - kd r`` (exact, held inputs), window starts."""
    pred = []
    for m in ms:
        a = float(np.exp(-kd_per_jz * m.dt_s))
        b = -(1.0 - a) * c_m / (kd_per_jz * jz) if kd_per_jz > 0 else -c_m * m.dt_s / jz
        pred.append(signal.lfilter([b], [1.0, -a], m.u[:, 0], zi=[a * m.x0[0]])[0])
    starts = np.cumsum([0] + [len(p) for p in pred[:-1]])
    return np.concatenate(pred), np.concatenate([m.y[:, 0] for m in ms]), starts


def fit(ms: list, kds: tuple[float, ...], with_c: bool, jz: float) -> tuple[float, float]:
    """``(c, kd/Jz)`` of least output error on ``ms``: ``c`` >= 0 by least squares for each ``kd`` of the grid."""
    best = (np.inf, 0.0, 0.0)
    for kd in kds:
        base, logged, _ = replay(ms, 0.0, kd, jz)
        g = replay(ms, 1.0, kd, jz)[0] - base
        c = max(float(g @ (logged - base) / (g @ g)), 0.0) if with_c else 0.0
        sse = float(np.sum((base + c * g - logged) ** 2))
        if sse < best[0]:
            best = (sse, c, kd)
    return best[1], best[2]


def study(name: str, cfg: ThrustConfig) -> None:
    r = identify_thrust(cfg)
    p = r.params
    per_flight, omega = [], []
    for spec in cfg.flights:
        f = load_flight(spec, cfg)
        d = f.model_data(r.spec.voltage)
        per_motor = fmu_total_thrust(p, f.pwm_us, battery_input_V(p, r.spec, d)) / N_MOTORS  # mean motor
        omega.append(np.sqrt(np.maximum(per_motor, 0.0) / p.k_thrust_N_s2).mean())
        per_flight.append(yaw_windows(f, d, p, r.spec))
    w = float(np.mean(omega))
    print(f"{name}: rotor yaw damping 8 b Omega / Jz = {8.0 * p.b_drag_N_m_s2 * w / p.Jz_kg_m2:.3f} 1/s with b as "
          f"identified ({p.b_drag_N_m_s2:.3g} N m s^2), {8.0 * B_DEFAULT * w / p.Jz_kg_m2:.3f} 1/s with the default "
          f"b ({B_DEFAULT:.3g}); mean Omega {w:.0f} rad/s")
    for label, kds, with_c in (("c alone (the FMU)", (0.0,), True), ("c and damping", KD_PER_JZ_1_S, True),
                               ("damping alone, c = 0", KD_PER_JZ_1_S, False)):
        cells = []
        for i, spec in enumerate(cfg.flights):
            train = [m for j, ms in enumerate(per_flight) if j != i for m in ms]
            c, kd = fit(train, kds, with_c, p.Jz_kg_m2)
            model, logged, starts = replay(per_flight[i], c, kd, p.Jz_kg_m2)
            hold = replay(per_flight[i], 0.0, 0.0, p.Jz_kg_m2)[0]
            si = skill_interval(logged, model, hold, starts)
            cells.append(f"{spec.name} {si.skill:+.2f} [{si.lo:+.2f}, {si.hi:+.2f}] (kd/Jz {kd:.1f})")
        print(f"  {label:<22} " + "; ".join(cells))


def main() -> int:
    if not all(Path(s.path).exists() for s in (*ERLE, *PX4)):
        print(f"bench/yaw_damping_study.py: needs {DATA}")
        return 2
    study("Erle", ThrustConfig(flights=ERLE))
    study("PX4", ThrustConfig(flights=PX4, fmu_mass_kg=1.2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
