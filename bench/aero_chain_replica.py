"""Replica of an excitation flight through an ArduPlane-like measurement chain: what each element does to the
output-error estimates, and whether modelling the chain brings every primary derivative back.

The plan (``uavfmu excite``: 3-2-1-1s and doublets on aileron, elevator and rudder, each block from trim) is
flown open loop, as in MANUAL, on the fixed-wing model with a random truth (each primary derivative scaled by
U(0.7, 1.3) from the Aerosonde set, seeded), through the chain of the shared SITL excitation log, logged as
ArduPlane 4.x logs it (``identification.logs.sensor_chain``, module docstring):

- physics stepped at ``--physics-rate`` (250 Hz, the HIL bench's rate);
- a ``--loop-rate`` (50 Hz, SCHED_LOOP_RATE) loop: the IMU sample of the tick, then the servo command, held
  until the next tick;
- the gyro and accelerometer passed through a 2-pole low-pass at ``--gyro-filter`` (20 Hz, INS_GYRO_FILTER /
  INS_ACCEL_FILTER) at the physics rate, logged every loop (IMU, stamped at the tick); airspeed every loop;
- white sensor noise (identification.flights.synthetic.NOISE);
- with ``--servo-log-rate`` (25 Hz in the shared log) RCOU and ATT (roll, pitch) written by a task of that rate:
  every ``loop/servo`` loops, stamped at that loop's tick, with that loop's command and attitude; which loops
  are logged is a random phase per block (the log task's phase against a pilot's or a script's blocks).
  Attitude between its samples is interpolated linearly, as ``identify aero`` reads the log.

The estimator (the output-error estimator ``identify aero`` uses, the 11 primary derivatives free, started at
the Aerosonde values) fits the logged records on the loop ticks:

- **chain not modelled**: each logged servo sample held until the next, no sensor filter;
- **filter modelled, commands held**: the sensor low-pass modelled (``output_filters``), commands held as logged
  (what ``identify aero --sensor-filters`` does, on a grid started at a tick);
- **filter and loop commands modelled** (with ``--servo-log-rate``): each loop's command bracketed by
  ``identification.logs.sensor_chain.LoopClock.bracket`` (an unlogged loop's between its logged neighbours),
  started at their mean and estimated with the parameters (``identification.estimation.unlogged_inputs``:
  Gauss-Newton steps with the commands profiled out); its intervals scaled by the Cramer-Rao std with the
  commands left strictly inside their brackets profiled out over the one without them (a command estimated at
  a neighbour's value is held there by its bound, ``Unlogged.pinned``); the coverage of the bound ``identify
  aero --estimate-unlogged`` prints, which leaves that uncertainty out, is printed beside it.

Printed per derivative: the mean ratio estimate / truth, the worst relative error, the share of 95 %
intervals (estimate +- 1.96 std) that cover the truth, and their median half-width over the RMS relative error
(both relative to the truth: every truth differs).

Target (the last variant): every primary derivative within 10 % of its truth for every truth, 95 % intervals
covering >= 90 %; exit 1 on a miss.

Run: ``python bench/aero_chain_replica.py [--truths 20] [--seed 0] [--servo-log-rate 25]`` (about 5 min on 2 shared
cores at ``--truths 20``).
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
from identification.aero.identify import PRIMARY, AeroOptions
from identification.estimation.oem import BOUNDS, Manoeuvre, OutputErrorEstimator, sensor_lowpass
from identification.estimation.unlogged_inputs import Unlogged, fit_with_unlogged, profiled_std
from identification.excite.design import ExciteOptions, plan_excitation
from identification.flights.synthetic import NOISE
from identification.logs.sensor_chain import ACCEL_OUTPUTS, GYRO_OUTPUTS, LoopClock

#: measurement noise (1 sigma) per fitted output, from the synthetic flights' sensor noise
SIGMA = {"roll_rad": NOISE["roll_rad"], "pitch_rad": NOISE["pitch_rad"], "airspeed_m_s": NOISE["airspeed_m_s"],
         **{n: NOISE["gyro_body_x_rad_s"] for n in GYRO_OUTPUTS},
         **{n: NOISE["accel_body_x_m_s2"] for n in ACCEL_OUTPUTS}}


def fly_block(sim: Simulator, p: np.ndarray, x0: np.ndarray, u_loop: np.ndarray, loop_dt: float, sub: int,
              fc_hz: float, rng: np.random.Generator) -> np.ndarray:
    """One block through the chain: servo commands ``u_loop`` held ``loop_dt`` each, physics ``sub`` steps per
    loop, gyro/accel low-passed at the physics rate; returns the outputs at the ticks t_1..t_N, with noise."""
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
    return logged + noise


def log_task(u_loop: np.ndarray, y_ticks: np.ndarray, every: int, phase: int, loop_dt: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What a log task running every ``every`` loops (first at loop ``phase``) writes: the servo commands of its
    loops with their tick times, and the attitude (ATT, same loops) interpolated between its samples at every
    tick as ``identify aero`` reads it. ``y_ticks[i]`` is the tick ``i + 1``."""
    n = len(u_loop)
    loops = np.arange(phase, n, every)
    t_servo = loops * loop_dt
    y = y_ticks.copy()
    ticks = np.arange(1, n + 1)
    att_loops = ticks[(ticks - phase) % every == 0]
    for name in ("roll_rad", "pitch_rad"):
        i = FIXED_WING_FIT_OUTPUTS.index(name)
        y[:, i] = np.interp(ticks, att_loops, y_ticks[att_loops - 1, i])
    return t_servo, u_loop[loops], y


def hold(t_log: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Each logged sample held until the next (before the first: the first)."""
    idx = np.clip(np.searchsorted(t_log, t + 1e-9, side="right") - 1, 0, len(t_log) - 1)
    return values[idx]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--truths", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--loop-rate", type=float, default=50.0)
    parser.add_argument("--physics-rate", type=float, default=250.0)
    parser.add_argument("--gyro-filter", type=float, default=20.0)
    parser.add_argument("--servo-log-rate", type=float, default=0.0,
                        help="log RCOU and ATT at this rate (the shared SITL log: 25 Hz); 0: every loop")
    parser.add_argument("--bound", choices=BOUNDS, default=AeroOptions().bound,
                        help="the estimator's data bound (default: identify aero's)")
    args = parser.parse_args()
    if not (1 <= args.truths <= 200 and 10 <= args.loop_rate <= 1000 and args.physics_rate >= args.loop_rate
            and 0 <= args.servo_log_rate <= args.loop_rate and 0 <= args.gyro_filter < args.physics_rate / 2):
        parser.error("--truths 1..200, --loop-rate 10..1000 Hz, --physics-rate >= loop rate, --servo-log-rate "
                     "0..loop rate, --gyro-filter below half the physics rate")
    sub = round(args.physics_rate / args.loop_rate)
    loop_dt = 1.0 / args.loop_rate
    every = round(args.loop_rate / args.servo_log_rate) if args.servo_log_rate else 1
    plan = plan_excitation(None, ExciteOptions(inputs=("3211", "doublet"), settle_s=1.0, tail_s=3.0,
                                               recovery_s=1.0, rate_hz=args.loop_rate, throttle_blocks=0))
    model = FixedWingModel(plan.params)
    sim = Simulator(model)
    p0 = np.array(model.params.starts())
    free = list(PRIMARY)
    weight = np.diag([1.0 / SIGMA[n] ** 2 for n in FIXED_WING_FIT_OUTPUTS])
    filters = {n: args.gyro_filter for n in (*GYRO_OUTPUTS, *ACCEL_OUTPUTS)}
    variants = {"chain not modelled": ({}, "hold"),
                f"filter {args.gyro_filter:g} Hz modelled, commands held": (filters, "hold")}
    if every > 1:
        variants[f"filter {args.gyro_filter:g} Hz and loop commands modelled"] = (filters, "loop")
    est_oe = {k: OutputErrorEstimator(model, p0, free, list(FIXED_WING_FIT_OUTPUTS), output_filters=f,
                                      bound=args.bound)
              for k, (f, _) in variants.items()}
    rng = np.random.default_rng(args.seed)
    ratios = {k: [] for k in variants}
    covered = {k: [] for k in variants}
    half = {k: [] for k in variants}  # relative 95 % half-widths
    tool = {k: [] for k in variants}  # covered by the bound identify aero prints (est.std)
    i_free = [model.params.index[n] for n in free]
    for k in range(args.truths):
        p = p0.copy()
        p[i_free] = p0[i_free] * rng.uniform(0.7, 1.3, len(free))
        tr = trim(model, p, plan.linear.va_m_s)
        logged = []
        for b in plan.blocks:
            n = round((b.end_s - b.start_s) / loop_dt)
            u = tr.u + b.deflection(b.start_s + np.arange(n) * loop_dt)
            y_ticks = fly_block(sim, p, tr.x, u, loop_dt, sub, args.gyro_filter, rng)
            logged.append((*log_task(u, y_ticks, every, int(rng.integers(every)), loop_dt), n))
        truth = p[i_free]
        for name, oe in est_oe.items():
            data, brackets = [], []
            for t_servo, u_servo, y, n in logged:
                ticks = np.arange(n) * loop_dt
                if variants[name][1] == "hold":
                    u_fit = hold(t_servo, u_servo, ticks)
                else:
                    clock = LoopClock(ticks, loop_dt)
                    cols = [clock.bracket(t_servo, u_servo[:, j], ticks) for j in range(u_servo.shape[1])]
                    before, after, share, logged_loop = (np.column_stack(x) for x in zip(*cols, strict=True))
                    u_fit = before + share * (after - before)
                    brackets.append(Unlogged(before, after, logged_loop))
                data.append(Manoeuvre(tr.x, u_fit, y, loop_dt))
            if brackets:
                est, used = fit_with_unlogged(oe, data, brackets, weight, max_iter=40, horizon_s=2.0)
                # the bound with the estimated commands as nuisance parameters, scaled onto the printed one
                plain = profiled_std(oe, est.values, used, [Unlogged(b.before, b.after, np.ones_like(b.logged))
                                                            for b in brackets], weight)
                inside = [b.pinned(m.u) for b, m in zip(brackets, used, strict=True)]
                sd = est.std[:len(free)] * profiled_std(oe, est.values, used, inside, weight) / plain
            else:
                est = oe.estimate(data, weight=weight, max_iter=40, horizon_s=2.0)
                sd = est.std[:len(free)]
            v = est.values[:len(free)]
            ratios[name].append(v / truth)
            covered[name].append(np.abs(v - truth) <= 1.96 * sd)
            half[name].append(1.96 * sd / np.abs(truth))
            tool[name].append(np.abs(v - truth) <= 1.96 * est.std[:len(free)])
        print(f"truth {k + 1}/{args.truths}: " + "; ".join(
            f"{name}: worst {np.max(np.abs(ratios[name][-1] - 1)) * 100:.1f} %" for name in variants), flush=True)
    ok = True
    target = list(variants)[-1]
    for name in variants:
        r, c, hw = np.array(ratios[name]), np.array(covered[name]), np.array(half[name])
        width = np.median(hw, axis=0) / np.sqrt(np.mean((r - 1) ** 2, axis=0))
        print(f"\n{name}: mean estimate / truth (worst |error| %, 95 % interval coverage, median half-width / RMS "
              "error)")
        for i, n in enumerate(free):
            print(f"  {n:14s} {r[:, i].mean():6.3f}  ({np.max(np.abs(r[:, i] - 1)) * 100:5.1f} %, "
                  f"{c[:, i].mean() * 100:5.1f} %, {width[i]:5.2f})")
        worst, cover = float(np.max(np.abs(r - 1))), float(c.mean())
        print(f"  all: worst {worst * 100:.1f} % (target <= 10 %), coverage {cover * 100:.1f} % (target >= 90 %)")
        if variants[name][1] == "loop":
            t = np.array(tool[name])
            print(f"  the bound identify aero prints (without the estimated commands' uncertainty): coverage "
                  f"{t.mean() * 100:.1f} % (per derivative {', '.join(f'{x * 100:.0f}' for x in t.mean(axis=0))} %)")
        if name == target:
            ok = worst <= 0.10 and cover >= 0.90
    print(f"\n{target}: {'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
