"""Why ``make demo``'s identified quadrotor inertia misses its truth: the thrust map held fixed, not the estimator.

The demo identifies the thrust map with ``identify thrust`` on its altitude flight (the four motors at one PWM,
1420-2000 us), then the inertia, motor lag, yaw torque and drag with ``identify quadrotor`` on its
stick-excitation flight (``uavfmu.demo.stick_flight``) through that map. The demo quadrotor flies the published
map (paper 000): trained on 1450-1554 us per motor, extended outside by the FMU (quadratic to idle below, linear
with a floored slope above), so kinked at both edges with the hover command (1531 us) just under the upper one.

This script runs ``identify quadrotor`` on the demo's stick flight with six thrust maps:

1. ``truth``: the published map the flight was flown with;
2. ``identify thrust``: the demo's own (``DEMO/quadrotor_identified.json``, written by ``make demo``): fitted to
   ``-m a_z - kd_z w``, ``kd_z`` from ``identify quadrotor``'s drag regression on the stick flight (``vertical_drag``);
3. ``identify thrust, drag left in``: ``identify thrust`` on the altitude flight fitted to ``-m a_z`` (the demo
   before it took the drag out);
4. ``best smooth, stick flight``: the demo map's rules (memberships kept) with their consequents fitted by least
   squares to the truth's thrust at every motor PWM of the stick flight (the best map of that family where the
   inertia is identified);
5. ``best smooth, altitude flight``: the same, fitted at the PWMs of the altitude flight
   (``DEMO/logs/quadrotor_flight.bin``): what a perfect ``identify thrust`` of that family could reach there;
6. ``identify thrust, drag known``: ``identify thrust`` on the altitude flight given the truth's vertical drag
   (``ThrustConfig.vertical_drag_N_s_m``): the measured thrust ``-m a_z - kd_z w`` is the rotor thrust, without the
   drag that follows the climb rate (up to 0.7 N there), which also moves the delay search to a negative delay.

Per map it prints its per-motor thrust at three PWMs (below, at and above the hover command) and the estimates of
``Jx``, ``Jy``, ``kd_z`` with their 95 % intervals against the truth. Then ``kd_z`` of the vertical drag
regression alone through ``identify thrust``'s map with 1 to 8 rules of the flexible thrust
(``identification.quadrotor.identify.ThrustNuisance``; the tool uses ``DRAG_THRUST_RULES``) and without it (the
scaled map alone). Exit 1 when the truth's map does not give ``Jx``,
``Jy`` within 1 % and ``kd_z`` within 10 % (then the estimator, not the map, would be at fault).

Run: ``make demo && .venv/bin/python bench/quadrotor_demo_map.py [--demo dist/demo]`` (about 3 min).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.quadrotor.params import QuadrotorParams
from fmu_models.quadrotor.thrust import command, constants_of, motor_thrust
from identification.logs.readers import read_log
from identification.quadrotor import identify as q
from identification.quadrotor.segments import Segment
from identification.thrust.workflow import FlightSpec, ThrustConfig, identify_thrust
from uavfmu.demo import ERLE_MASS_KG, stick_flight

CHECKED = ("Jx_kg_m2", "Jy_kg_m2", "kd_z_N_s_m")
#: PWMs [us] below and above the hover command at which each map's thrust is printed
AROUND_HOVER_US = (-130.0, 0.0, 170.0)


def thrust_n(params: QuadrotorParams, pwm_us: np.ndarray) -> np.ndarray:
    """Per-motor thrust [N] of ``params``' map at ``pwm_us`` (the FMU's function)."""
    c = constants_of(params)
    return np.array([motor_thrust(params.thrust_map, float(p), params.battery_nominal_V, c, N_MOTORS)
                     for p in np.ravel(pwm_us)]).ravel()


def best_smooth(shape: QuadrotorParams, truth: QuadrotorParams, pwm_us: np.ndarray) -> QuadrotorParams:
    """``shape``'s map (a feature map over ``u^2, u``) with its consequents fitted by least squares to the truth's
    thrust at ``pwm_us``; its band widened to the PWMs' lowest command."""
    amap = shape.thrust_map
    u = command(pwm_us, shape.pwm_idle_us, shape.pwm_full_us)
    w = np.column_stack([np.exp(-(((u - m) / s) ** 2)) for m, s in zip(amap.mf_mean[0], amap.mf_sigma[0],
                                                                       strict=True)])
    w /= w.sum(axis=1, keepdims=True)
    cols = np.column_stack([c for r in range(w.shape[1]) for c in (w[:, r] * u * u, w[:, r] * u)])
    beta = np.linalg.lstsq(cols, thrust_n(truth, pwm_us), rcond=None)[0]
    cons = tuple((float(beta[2 * r]), float(beta[2 * r + 1])) for r in range(w.shape[1]))
    lo = min(float(amap.input_range[0][0]), float(u[u > 0].min()))
    return dataclasses.replace(shape, thrust_map=dataclasses.replace(
        amap, consequents=cons, input_range=((lo, float(amap.input_range[0][1])),)))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--demo", type=Path, default=Path("dist/demo"), help="make demo's work folder")
    ap.add_argument("--stick-seeds", default="", help="also run the demo's chain on stick flights of these noise "
                    "seeds (comma-separated): kd_z by vertical_drag through the map with the drag left in, the map "
                    "again without the drag, Jx and Jy through both")
    args = ap.parse_args(argv)
    thrust_file, altitude_log = args.demo / "quadrotor_identified.json", args.demo / "logs" / "quadrotor_flight.bin"
    missing = [str(p) for p in (thrust_file, altitude_log) if not p.exists()]
    if missing:
        print(f"not found: {', '.join(missing)} (run make demo first)")
        return 2
    flight = stick_flight()
    truth = flight.truth
    demo_map = QuadrotorParams.from_dict(json.loads(thrust_file.read_text())["quadrotor"])
    stick_pwm = np.concatenate([flight.log.signal(f"motor_{k}_pwm_us").values for k in range(1, N_MOTORS + 1)])
    alt = read_log(altitude_log)
    alt_pwm = np.concatenate([alt.signal(f"motor_{k}_pwm_us").values for k in range(1, N_MOTORS + 1)])
    alt_pwm = alt_pwm[alt_pwm > truth.pwm_idle_us + 150.0]
    spec = (FlightSpec(altitude_log, ERLE_MASS_KG),)
    known = identify_thrust(ThrustConfig(flights=spec, vertical_drag_N_s_m=truth.kd_z_N_s_m))
    left_in = identify_thrust(ThrustConfig(flights=spec))
    lag_s = json.loads(thrust_file.with_suffix(".metrics.json").read_text())["flights"][0]["lag_s"]
    print(f"identify thrust's delay: the demo's {lag_s:+.3f} s, drag left in {left_in.flights[0]['lag_s']:+.3f} s, "
          f"drag known {known.flights[0]['lag_s']:+.3f} s")
    maps = {"truth": truth, "identify thrust": demo_map, "identify thrust, drag left in": left_in.params,
            "best smooth, stick flight": best_smooth(demo_map, truth, stick_pwm),
            "best smooth, altitude flight": best_smooth(demo_map, truth, alt_pwm),
            "identify thrust, drag known": known.params}
    hover = float(np.median(stick_pwm))
    at = hover + np.array(AROUND_HOVER_US)
    print(f"stick flight: motor PWM 1/50/99 % {np.percentile(stick_pwm, [1, 50, 99]).round(0)} us; "
          f"altitude flight: {np.percentile(alt_pwm, [1, 50, 99]).round(0)} us")
    segs = [Segment(b.start_s, b.end_s, b.axis) for b in flight.blocks]
    failed = False
    for name, start in maps.items():
        res = q.identify_quadrotor(flight.log, start, q.QuadrotorOptions(segments=segs))
        est = res.estimates()
        t_at = " ".join(f"{v:.3f}" for v in thrust_n(start, at))
        parts = []
        for n in CHECKED:
            e, tr = est[n], getattr(truth, n)
            lo, hi = e["ci95"]
            parts.append(f"{n} {e['value']:.4g} [{lo:.4g}, {hi:.4g}] {100 * (e['value'] / tr - 1):+.1f} %"
                         f"{'' if lo <= tr <= hi else ' MISSED'}")
            if name == "truth":
                failed |= abs(e["value"] / tr - 1) > (0.10 if n == "kd_z_N_s_m" else 0.01)
        print(f"{name:<29} T [N] {t_at}  " + "  ".join(parts), flush=True)
    windows = q._drag_windows([flight.log], demo_map, *q._windows([flight.log], demo_map,
                                                                 q.QuadrotorOptions(segments=segs), []))
    thrust_of = q.MotorThrust(demo_map).total
    rate = q.QuadrotorOptions().rate_hz
    by_rules = {"scaled map alone": q.drag_equation_error([flight.log], windows, demo_map, thrust_of, rate)}
    span = q.ThrustNuisance.over([flight.log], windows, demo_map).centres
    for k in range(1, 9):
        nu = q.ThrustNuisance(demo_map, float(span[0]), float(span[-1]), rules=k)
        by_rules[f"{k} rules"] = q.drag_equation_error([flight.log], windows, demo_map, thrust_of, rate, nuisance=nu)
    print("kd_z through identify thrust's map, by the flexible thrust's rules: " + ", ".join(
        f"{k} {d['kd_z_N_s_m']['value']:.3f} +- {d['kd_z_N_s_m']['std']:.3f}" for k, d in by_rules.items()))
    for seed in (int(v) for v in args.stick_seeds.split(",") if v.strip()):
        other = stick_flight(seed)
        opt = q.QuadrotorOptions(segments=[Segment(b.start_s, b.end_s, b.axis) for b in other.blocks])
        kd = q.vertical_drag(other.log, left_in.params, opt)
        again = identify_thrust(ThrustConfig(flights=spec, vertical_drag_N_s_m=kd["value"]))
        errs = []
        for params in (again.params, left_in.params):
            est = q.identify_quadrotor(other.log, params, opt).estimates()
            errs += [100.0 * (est[n]["value"] / getattr(other.truth, n) - 1.0) for n in ("Jx_kg_m2", "Jy_kg_m2")]
        print(f"stick seed {seed}: kd_z {kd['value']:.3f} +- {kd['std']:.3f}, delay {again.flights[0]['lag_s']:+.3f} s,"
              f" Jx {errs[0]:+.1f} %, Jy {errs[1]:+.1f} % (drag left in: {errs[2]:+.1f}, {errs[3]:+.1f} %)", flush=True)
    print(f"truth: Jx {truth.Jx_kg_m2:g}, Jy {truth.Jy_kg_m2:g}, kd_z {truth.kd_z_N_s_m:g}; T: per-motor thrust at "
          f"{', '.join(f'{v:.0f}' for v in at)} us (the median motor PWM of the stick flight and around it)")
    print("the truth's map " + ("does NOT recover the truth: the estimator is at fault" if failed else
                                "recovers the truth: the misses of the other maps are the thrust map's"))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
