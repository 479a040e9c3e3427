"""Replica of an excitation flight through an ArduPlane-like measurement chain: what each element does to the
output-error estimates, and whether modelling the chain brings every primary derivative back.

The plan (``uavfmu excite``: 3-2-1-1s and doublets on aileron, elevator and rudder, each block from trim) is
flown open loop, as in MANUAL, on the fixed-wing model with a random truth (each primary derivative scaled by
U(0.7, 1.3) from the Aerosonde set, seeded), through the chain of the shared SITL excitation log:

- physics stepped at ``--physics-rate`` (250 Hz, the HIL bench's rate);
- a ``--loop-rate`` (50 Hz, SCHED_LOOP_RATE) loop computing the servo command, held until the next loop;
- the gyro and accelerometer passed through a 2-pole low-pass at ``--gyro-filter`` (20 Hz, INS_GYRO_FILTER /
  INS_ACCEL_FILTER) at the physics rate, then logged once per loop; attitude and airspeed logged unfiltered;
- white sensor noise (identification.flights.synthetic.NOISE);
- with ``--servo-log-rate`` (25 Hz in the shared log) the servo commands logged at that rate only, each held
  until the next log sample (a command that changed between log samples shows late).

The estimator (the output-error estimator ``identify aero`` uses, the 11 primary derivatives free, started at
the Aerosonde values) then fits the logged records twice: without the chain (model outputs compared with the log
as they are) and with the sensor filter modelled (``output_filters``; with ``--servo-log-rate`` also the logged
commands interpolated linearly at the loops between log samples: such a loop held one of its two neighbours'
commands, their mean is the unbiased guess). Printed per derivative: the mean ratio
estimate / truth for each, the worst relative error, and the share of 95 % intervals (estimate +- 1.96 std)
that cover the truth.

Target (modelled chain): every primary derivative within 10 % of its truth for every truth, 95 % intervals
covering >= 90 %; exit 1 on a miss.

Run: ``python bench/aero_chain_replica.py [--truths 20] [--seed 0]`` (about 2 min on one core).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import trim
from fmu_models.signals.names import FIXED_WING_FIT_OUTPUTS
from identification.aero.identify import PRIMARY
from identification.estimation.oem import Manoeuvre, OutputErrorEstimator, sensor_lowpass
from identification.excite.design import ExciteOptions, plan_excitation
from identification.flights.synthetic import NOISE
from identification.logs.sensor_chain import ACCEL_OUTPUTS, GYRO_OUTPUTS

#: measurement noise (1 sigma) per fitted output, from the synthetic flights' sensor noise
SIGMA = {"roll_rad": NOISE["roll_rad"], "pitch_rad": NOISE["pitch_rad"], "airspeed_m_s": NOISE["airspeed_m_s"],
         **{n: NOISE["gyro_body_x_rad_s"] for n in GYRO_OUTPUTS},
         **{n: NOISE["accel_body_x_m_s2"] for n in ACCEL_OUTPUTS}}


def fly_block(sim: Simulator, p: np.ndarray, x0: np.ndarray, u_loop: np.ndarray, loop_dt: float, sub: int,
              fc_hz: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """One block through the chain: servo commands ``u_loop`` held ``loop_dt`` each, physics ``sub`` steps per
    loop, gyro/accel low-passed at the physics rate; returns the logged (commands, outputs at t_1..t_N)."""
    dt = loop_dt / sub
    n = len(u_loop)
    _, _, y = sim.run(lambda t: u_loop[min(int(t / loop_dt + 1e-9), n - 1)], p, n * loop_dt, dt,
                      x0=np.asarray(x0, float))
    idx = sim.model.outputs.index
    cols = {name: y[:, idx[name]].copy() for name in FIXED_WING_FIT_OUTPUTS}
    if fc_hz > 0:
        b, a, zi = sensor_lowpass(fc_hz, dt)
        for name in (*GYRO_OUTPUTS, *ACCEL_OUTPUTS):
            cols[name] = lfilter(b, a, cols[name], zi=zi * cols[name][0])[0]
    logged = np.column_stack([cols[name][sub::sub][:n] for name in FIXED_WING_FIT_OUTPUTS])
    noise = rng.normal(0.0, [SIGMA[name] for name in FIXED_WING_FIT_OUTPUTS], logged.shape)
    return u_loop, logged + noise


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--truths", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--loop-rate", type=float, default=50.0)
    parser.add_argument("--physics-rate", type=float, default=250.0)
    parser.add_argument("--gyro-filter", type=float, default=20.0)
    parser.add_argument("--servo-log-rate", type=float, default=0.0,
                        help="log the servo commands at this rate (the shared SITL log: 25 Hz); 0: every loop")
    args = parser.parse_args()
    sub = round(args.physics_rate / args.loop_rate)
    loop_dt = 1.0 / args.loop_rate
    plan = plan_excitation(None, ExciteOptions(inputs=("3211", "doublet"), settle_s=1.0, tail_s=3.0,
                                               recovery_s=1.0, rate_hz=args.loop_rate, throttle_blocks=0))
    model = FixedWingModel(plan.params)
    sim = Simulator(model)
    p0 = np.array(model.params.starts())
    free = list(PRIMARY)
    weight = np.diag([1.0 / SIGMA[n] ** 2 for n in FIXED_WING_FIT_OUTPUTS])
    variants = {"chain not modelled": {}, f"sensor low-pass {args.gyro_filter:g} Hz modelled":
                {n: args.gyro_filter for n in (*GYRO_OUTPUTS, *ACCEL_OUTPUTS)}}
    est_oe = {k: OutputErrorEstimator(model, p0, free, list(FIXED_WING_FIT_OUTPUTS), output_filters=f)
              for k, f in variants.items()}
    rng = np.random.default_rng(args.seed)
    ratios = {k: [] for k in variants}
    covered = {k: [] for k in variants}
    i_free = [model.params.index[n] for n in free]
    for k in range(args.truths):
        p = p0.copy()
        p[i_free] = p0[i_free] * rng.uniform(0.7, 1.3, len(free))
        tr = trim(model, p, plan.linear.va_m_s)
        data = []
        for b in plan.blocks:
            t = np.arange(round((b.end_s - b.start_s) / loop_dt)) * loop_dt
            u = tr.u + b.deflection(b.start_s + t)
            u_log, y_log = fly_block(sim, p, tr.x, u, loop_dt, sub, args.gyro_filter, rng)
            if args.servo_log_rate:  # what the log shows: the command at each log sample, held until the next
                every = round(args.loop_rate / args.servo_log_rate)
                u_log = u_log[(np.arange(len(u_log)) // every) * every]
            data.append(Manoeuvre(tr.x, u_log, y_log, loop_dt, f"block {b.index}"))
        truth = p[i_free]
        for name, oe in est_oe.items():
            est = oe.estimate(data, weight=weight, max_iter=40, horizon_s=2.0)
            if args.servo_log_rate and name != "chain not modelled":
                # modelled: a loop between two logged commands held either of them; take their mean (linear
                # interpolation of the logged commands at the loop times)
                every = round(args.loop_rate / args.servo_log_rate)
                mid = []
                for m in data:
                    loops = np.arange(len(m.u))
                    nxt = np.minimum((loops // every + 1) * every, len(m.u) - 1)
                    w = (loops % every / every)[:, None]
                    mid.append(Manoeuvre(m.x0, (1 - w) * m.u + w * m.u[nxt], m.y, m.dt_s))
                est = oe.estimate(mid, weight=weight, max_iter=40, horizon_s=2.0)
            v, sd = est.values[:len(free)], est.std[:len(free)]
            ratios[name].append(v / truth)
            covered[name].append(np.abs(v - truth) <= 1.96 * sd)
        print(f"truth {k + 1}/{args.truths}: " + "; ".join(
            f"{name}: worst {np.max(np.abs(ratios[name][-1] - 1)) * 100:.1f} %" for name in variants), flush=True)
    ok = True
    for name in variants:
        r, c = np.array(ratios[name]), np.array(covered[name])
        print(f"\n{name}: mean estimate / truth (worst |error| %, 95 % interval coverage)")
        for i, n in enumerate(free):
            print(f"  {n:14s} {r[:, i].mean():6.3f}  ({np.max(np.abs(r[:, i] - 1)) * 100:5.1f} %, "
                  f"{c[:, i].mean() * 100:5.1f} %)")
        worst, cover = float(np.max(np.abs(r - 1))), float(c.mean())
        print(f"  all: worst {worst * 100:.1f} % (target <= 10 %), coverage {cover * 100:.1f} % (target >= 90 %)")
        if name != "chain not modelled":
            ok = worst <= 0.10 and cover >= 0.90
    print(f"\nmodelled chain: {'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
