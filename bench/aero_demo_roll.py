"""The demo's roll identification over sensor-noise seeds: is its printed interval as wide as its actual error?

`make demo` flies the fixed-wing FMU once in closed loop (``uavfmu.demo.record_flights``) and writes one
DataFlash log with seeded white sensor noise (seed 2 by default), then identifies C_ell_p and C_ell_delta_a from
roll and roll rate (``identify aero``, ``--free C_ell_p,C_ell_delta_a``, no consider covariance: the demo's plant
flies the FMU's own coefficients). One log says little about an interval: here the same flight is written with
``--seeds`` noise seeds (the demo's among them) and identified each time as the demo does. Printed per seed:
estimate, error, printed std and its parts (AR coloured Cramér-Rao, segment bootstrap, which one was printed);
then per derivative the coverage of the 95 % intervals, the median half-width over the RMS error across seeds,
and the demo seed's half-width over its own error.

Run: ``.venv/bin/python bench/aero_demo_roll.py [--seeds 8] [--fmu dist/fixed_wing.fmu]`` (builds the FMU into a
temporary folder without ``--fmu``; 20-40 s per seed on 2 cores). Exit 1 when a derivative's coverage is below
0.90 or its median half-width above 2x the RMS error.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.aero.identify import AeroOptions, identify_aero
from identification.flights import synthetic
from identification.flights.scenarios import (
    FixedWingAutopilot,
    SampleHold,
    fixed_wing_bank_profile,
    fixed_wing_excitation,
    fixed_wing_start,
    fly,
)
from identification.logs.readers import read_log
from uavfmu.demo import ROLL_FREE

DEMO_SEED = 2  #: the fixed-wing log's noise seed in ``make demo`` (``--seed 1`` + 1)


def fixed_wing_fmu(out: Path) -> Path:
    """The demo's fixed-wing FMU, built for this machine into ``out``."""
    from build_fmus import BuildOptions, build
    from fmu_models.fmi.zigcc import host_platform

    paths = build(None, out, options=BuildOptions(platforms=(host_platform().fmi_name,)))
    return next(p for p in paths if p.stem == "fixed_wing")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--fmu", type=Path, default=None)
    parser.add_argument("--bound", choices=("ar", "bootstrap"), default="ar")
    args = parser.parse_args()
    if not 2 <= args.seeds <= 100:
        parser.error("--seeds must be in 2..100")
    names = ROLL_FREE.split(",")
    truth = {n: float(getattr(FixedWingParams(), n)) for n in names}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        fmu = args.fmu or fixed_wing_fmu(Path(tmp))
        start, inputs, pitch = fixed_wing_start()
        ap = SampleHold(FixedWingAutopilot(inputs, pitch, fixed_wing_bank_profile, fixed_wing_excitation), 0.02)
        wing = fly(fmu, ap, 80.0, 0.01, start)  # the demo's identification flight
        print(f"{'seed':>4} {'derivative':<14} {'estimate':>9} {'error':>9} {'std':>8} {'CR ar':>8} {'boot':>8}  bound")
        for seed in range(DEMO_SEED, DEMO_SEED + args.seeds):
            path = synthetic.write_log(Path(tmp) / f"fixed_wing_{seed}.bin", wing, noise=True, seed=seed)
            flog = read_log(path)
            res = identify_aero(flog, PwmMapping.from_ardupilot(flog.params), FixedWingParams(), AeroOptions(
                free=names, outputs=("roll_rad", "rate_body_x_rad_s"), consider=False, bound=args.bound))
            est = res.fit.estimate
            small = est.small_sample()
            boot = est.bootstrap_std if est.bootstrap_std is not None else np.full(est.n_global, np.nan)
            row = {}
            for n in names:
                i = est.names.index(n)
                err = float(est.values[i]) - truth[n]
                row[n] = (err, float(est.std[i]))
                print(f"{seed:4d} {n:<14} {est.values[i]:9.4f} {err:+9.4f} {est.std[i]:8.4f} {est.crb_std[i]:8.4f} "
                      f"{boot[i]:8.4f}  {'small-sample' if n in small else est.bound_method.split(' (')[0]}")
            rows.append(row)
    ok = True
    print(f"\nover {args.seeds} noise seeds of the demo's flight (bound {args.bound!r}):")
    for n in names:
        err = np.array([r[n][0] for r in rows])
        hw = 1.96 * np.array([r[n][1] for r in rows])
        cov = float(np.mean(np.abs(err) <= hw))
        rms = float(np.sqrt(np.mean(err**2)))
        ratio = float(np.median(hw)) / rms
        ok &= cov >= 0.9 and ratio <= 2.0
        print(f"  {n:<14} truth {truth[n]:+.4f}: coverage {cov:.2f}, mean error {np.mean(err):+.4f}, RMS error "
              f"{rms:.4f}, median half-width {np.median(hw):.4f} = {ratio:.2f} x the RMS error; demo seed "
              f"{DEMO_SEED}: half-width {hw[0]:.4f} = {hw[0] / max(abs(err[0]), 1e-12):.1f} x its error "
              f"{abs(err[0]):.4f}")
    print("targets: coverage >= 0.90, median half-width <= 2 x the RMS error -> " + ("PASS" if ok else "FAIL"))
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
