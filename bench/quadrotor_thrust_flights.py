"""Which thrust-identification flight gives the demo quadrotor's inertia: flight designs, drag left in or known.

The demo identifies the inertia through the thrust map ``identify thrust`` fits on an altitude flight (the four
motors at one PWM). This study flies other thrust flights on the demo quadrotor's FMU (the published map, no motor
lag, ``kd_z`` 0.25) with the demo's closed loop, logs them as the demo does (DataFlash, sensor noise), fits the map
on each with the vertical drag left in ``-m a_z`` and with the truth's ``kd_z`` given
(``ThrustConfig.vertical_drag_N_s_m``), and runs ``identify quadrotor`` through it on the demo's stick flight:

- ``demo altitude sines``: the demo's own reference (``uavfmu.demo.quadrotor_altitude``: 2.5 m over 9 s and 1 m
  over 3.1 s about 10 m);
- ``small altitude sines``: the same periods at 1.0 and 0.4 m (per-motor commands closer to hover, slower climbs);
- ``collective doublets``: an altitude hold at 10 m with all four motors' PWM stepped together by +-40, 80, 120,
  160 us (0.25 s each way, 0.5 s apart), the throttle pulses a pilot would fly.

Per design it prints the per-motor PWM flown (1 / 50 / 99 %), and per fit the delay found, the map's rules and
band, and ``Jx``'s error. Exit 1 when no design gives ``Jx`` within 10 % with the drag known.

Run: ``make demo && .venv/bin/python bench/quadrotor_thrust_flights.py [--fmu dist/quadrotor.fmu] [--seed 1]``
(about 6 min on two free cores).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.quadrotor.constants import N_MOTORS
from identification.flights import synthetic
from identification.flights.scenarios import QuadrotorAutopilot, SampleHold, fly, published_thrust_inverse
from identification.quadrotor import identify as q
from identification.thrust.workflow import FlightSpec, ThrustConfig, identify_thrust
from uavfmu.demo import ERLE_MASS_KG, quadrotor_altitude, stick_flight, stick_segments

DOUBLET_US = (40.0, 80.0, 120.0, 160.0)  #: collective doublet amplitudes [us], cycled, sign alternating per cycle
DOUBLET_HALF_S, DOUBLET_GAP_S, DOUBLET_START_S = 0.25, 0.5, 5.0


def small_sines(t: float) -> float:
    """Altitude reference [m]: the demo's climb to 10 m, then its two sines at 1.0 and 0.4 m."""
    if t < 4.0:
        return 10.0 * t / 4.0
    return 10.0 + 1.0 * math.sin(2 * math.pi * (t - 4.0) / 9.0) + 0.4 * math.sin(2 * math.pi * (t - 4.0) / 3.1)


def hold_10_m(t: float) -> float:
    """Altitude reference [m]: climb to 10 m in 4 s, then hold."""
    return 10.0 * t / 4.0 if t < 4.0 else 10.0


def collective_doublets(t: float) -> float:
    """PWM added to every motor [us]: doublets of growing amplitude (:data:`DOUBLET_US`), a gap between."""
    if t < DOUBLET_START_S:
        return 0.0
    cycle = 2 * DOUBLET_HALF_S + DOUBLET_GAP_S
    k = int((t - DOUBLET_START_S) // cycle)
    tt = t - DOUBLET_START_S - k * cycle
    a = DOUBLET_US[k % len(DOUBLET_US)] * (1.0 if (k // len(DOUBLET_US)) % 2 == 0 else -1.0)
    return a if tt < DOUBLET_HALF_S else -a if tt < 2 * DOUBLET_HALF_S else 0.0


class Collective:
    """The autopilot's motor commands plus a collective offset ``offset(t)`` [us], clipped to 1000-2000 us."""

    def __init__(self, autopilot: Callable, offset: Callable[[float], float]) -> None:
        self.autopilot, self.offset = autopilot, offset

    def __call__(self, t: float, y: dict[str, float]) -> dict[str, float]:
        d = self.offset(t)
        return {k: min(max(v + d, 1000.0), 2000.0) for k, v in self.autopilot(t, y).items()}


DESIGNS: dict[str, Callable[[], Callable]] = {
    "demo altitude sines": lambda: QuadrotorAutopilot(quadrotor_altitude, published_thrust_inverse()),
    "small altitude sines": lambda: QuadrotorAutopilot(small_sines, published_thrust_inverse()),
    "collective doublets": lambda: Collective(QuadrotorAutopilot(hold_10_m, published_thrust_inverse()),
                                              collective_doublets),
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmu", type=Path, default=Path("dist/quadrotor.fmu"), help="the demo quadrotor's FMU")
    ap.add_argument("--seed", type=int, default=1, help="sensor-noise seed of the thrust flights' logs")
    args = ap.parse_args(argv)
    if not args.fmu.exists():
        print(f"not found: {args.fmu} (run make demo first)")
        return 2
    stick = stick_flight()
    truth = stick.truth
    opt = q.QuadrotorOptions(segments=stick_segments(stick))
    best = math.inf
    with tempfile.TemporaryDirectory() as tmp:
        for name, make in DESIGNS.items():
            rec = fly(args.fmu, SampleHold(make(), 0.02), 60.0, 0.01)
            log = synthetic.write_log(Path(tmp) / f"{name.replace(' ', '_')}.bin", rec, noise=True, seed=args.seed)
            pwm = np.concatenate([rec.inputs[f"pwm_{k}_us"][500:] for k in range(1, N_MOTORS + 1)])
            print(f"{name}: per-motor PWM 1 / 50 / 99 % {np.percentile(pwm, [1, 50, 99]).round(0)} us", flush=True)
            for drag in (None, truth.kd_z_N_s_m):
                th = identify_thrust(ThrustConfig(flights=(FlightSpec(log, ERLE_MASS_KG),), vertical_drag_N_s_m=drag))
                est = q.identify_quadrotor(stick.log, th.params, opt).estimates()["Jx_kg_m2"]["value"]
                err = 100.0 * (est / truth.Jx_kg_m2 - 1.0)
                if drag is not None:
                    best = min(best, abs(err))
                band = th.params.thrust_map.input_range[0]
                print(f"  {'drag known' if drag else 'drag left in':<13} delay {th.flights[0]['lag_s']:+.3f} s, "
                      f"{th.spec.describe()}, band u {band[0]:.3f}-{band[1]:.3f}: Jx {est:.5g} ({err:+.1f} %)",
                      flush=True)
    print(f"truth Jx {truth.Jx_kg_m2:g}; best with the drag known: {best:.1f} % off")
    return 0 if best < 10.0 else 1


if __name__ == "__main__":
    sys.exit(main())
