"""Systematic errors of the chain fit: the replica's chain flown noise-free, so any error left is the method's.

One truth of ``bench/aero_chain_replica.py`` (the plan, the chain, the same generator; ``--seed`` picks the
truth) is flown with the sensor noise set to zero, and the 11 primary derivatives are fitted from the truth as
start, once per case:

- ``plant N Hz, fit K sub-steps, filter F Hz``: every loop's command logged; the plant stepped ``N / 50`` times per
  50 Hz loop with its gyro and accelerometer low-passed at ``F`` Hz at that rate (0: none), the estimator's model
  at ``K`` RK4 sub-steps per sample with the same filter run at the sub-step (``OutputErrorEstimator(substeps=K)``;
  ``auto``: ``oem.filter_substeps``, the tool's default);
- ``25 Hz servo log``: the same with the plant at 250 Hz and the 20 Hz filter, commands logged every second loop
  as ArduPlane's RCOU: fitted with the true commands, with the mean of the logged neighbours, with 4 rounds of
  alternating command estimate (``refine_unlogged``) and refit (the method before 2026-11-29), and with the
  unlogged commands estimated as the tool does (``identification.estimation.unlogged_inputs.fit_with_unlogged``:
  profiled Gauss-Newton steps).

Printed: the relative error of every primary derivative, per case. Exit 1 when a tool default (``auto``
sub-steps; unlogged commands estimated) leaves any derivative more than :data:`TOLERANCE` off.

Run: ``python bench/aero_chain_bias.py [--seed 0]`` (about 1 min on 2 shared cores).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import aero_chain_replica as acr

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import trim
from fmu_models.signals.names import FIXED_WING_FIT_OUTPUTS
from identification.aero.identify import PRIMARY
from identification.estimation.oem import Manoeuvre, OutputErrorEstimator
from identification.estimation.unlogged_inputs import Unlogged, fit_with_unlogged, refine_unlogged
from identification.excite.design import ExciteOptions, plan_excitation
from identification.logs.sensor_chain import ACCEL_OUTPUTS, GYRO_OUTPUTS, LoopClock

#: largest relative error a tool default may leave on noise-free data
TOLERANCE = 0.002
LOOP_DT = 0.02
#: (plant rate [Hz], estimator sub-steps or None for the tool's default, filter cut-off [Hz])
CASES = ((250.0, 1, 0.0), (250.0, 1, 20.0), (250.0, 2, 20.0), (250.0, 3, 20.0), (250.0, 5, 20.0),
         (250.0, None, 20.0), (1000.0, 5, 20.0), (1000.0, 10, 20.0), (1000.0, None, 20.0))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    weight = np.diag([1.0 / acr.SIGMA[n] ** 2 for n in FIXED_WING_FIT_OUTPUTS])
    acr.SIGMA = {n: 0.0 for n in acr.SIGMA}  # noise-free plant (fly_block reads it)
    plan = plan_excitation(None, ExciteOptions(inputs=("3211", "doublet"), settle_s=1.0, tail_s=3.0,
                                               recovery_s=1.0, rate_hz=1.0 / LOOP_DT, throttle_blocks=0))
    model = FixedWingModel(plan.params)
    sim = Simulator(model)
    p0 = np.array(model.params.starts())
    free = list(PRIMARY)
    i_free = [model.params.index[n] for n in free]
    rng = np.random.default_rng(args.seed)
    p = p0.copy()
    p[i_free] = p0[i_free] * rng.uniform(0.7, 1.3, len(free))
    tr = trim(model, p, plan.linear.va_m_s)
    truth = p[i_free]
    inputs = []
    for b in plan.blocks:
        n = round((b.end_s - b.start_s) / LOOP_DT)
        inputs.append(tr.u + b.deflection(b.start_s + np.arange(n) * LOOP_DT))
    print(f"{'case':<52} " + " ".join(f"{n[2:]:>9}" for n in free))
    ok = True

    def show(label: str, values: np.ndarray, default: bool) -> None:
        nonlocal ok
        rel = values[:len(free)] / truth - 1.0
        bad = default and float(np.max(np.abs(rel))) > TOLERANCE
        ok &= not bad
        print(f"{label:<52} " + " ".join(f"{100 * r:+8.2f}%" for r in rel) + ("  <- above tolerance" if bad else ""),
              flush=True)

    def filters(fc: float) -> dict[str, float]:
        return {n: fc for n in (*GYRO_OUTPUTS, *ACCEL_OUTPUTS)} if fc else {}

    for rate, sub, fc in CASES:
        k = round(rate * LOOP_DT)
        oe = OutputErrorEstimator(model, p0, free, list(FIXED_WING_FIT_OUTPUTS), output_filters=filters(fc),
                                  substeps=sub)
        data = [Manoeuvre(tr.x, u, acr.fly_block(sim, p, tr.x, u, LOOP_DT, k, fc, rng), LOOP_DT) for u in inputs]
        est = oe.estimate(data, theta0=truth, weight=weight, max_iter=40)
        label = f"plant {rate:g} Hz, fit {sub or f'auto ({oe.substeps_for(LOOP_DT)})'} sub-steps, filter {fc:g} Hz"
        show(label, est.values, sub is None)
    oe = OutputErrorEstimator(model, p0, free, list(FIXED_WING_FIT_OUTPUTS), output_filters=filters(20.0))
    true_data, mean_data, brackets = [], [], []
    for u in inputs:
        n = len(u)
        y = acr.fly_block(sim, p, tr.x, u, LOOP_DT, 5, 20.0, rng)
        t_servo, u_servo, y = acr.log_task(u, y, 2, int(rng.integers(2)), LOOP_DT)
        ticks = np.arange(n) * LOOP_DT
        clock = LoopClock(ticks, LOOP_DT)
        cols = [clock.bracket(t_servo, u_servo[:, j], ticks) for j in range(u_servo.shape[1])]
        before, after, share, logged = (np.column_stack(x) for x in zip(*cols, strict=True))
        true_data.append(Manoeuvre(tr.x, u, y, LOOP_DT))
        mean_data.append(Manoeuvre(tr.x, before + share * (after - before), y, LOOP_DT))
        brackets.append(Unlogged(before, after, logged))
    show("25 Hz servo log, true commands", oe.estimate(true_data, theta0=truth, weight=weight, max_iter=40).values,
         False)
    mean = oe.estimate(mean_data, weight=weight, max_iter=40, horizon_s=2.0)
    show("25 Hz servo log, mean of the neighbours", mean.values, False)
    alt, cur = mean, mean_data
    for _ in range(4):  # the method before 2026-11-29: alternate command estimate and refit
        cur = refine_unlogged(oe, alt.values, cur, brackets, weight)
        alt = oe.estimate(cur, theta0=alt.values, weight=weight, max_iter=40)
    show("25 Hz servo log, 4 alternating rounds (old)", alt.values, False)
    est, _ = fit_with_unlogged(oe, mean_data, brackets, weight, start=mean, max_iter=40)
    show("25 Hz servo log, unlogged commands estimated", est.values, True)
    print(f"tool defaults within {100 * TOLERANCE:g} %: {'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
