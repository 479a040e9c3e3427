"""Benchmark: do the prediction bands of ``validate --mc`` cover flights they were not learned on?

Leave-one-flight-out on the shared quadrotor flights (three Erle, two PX4 csv): per fold, ``identify thrust`` on
the training flights writes the parameter file (thrust map, covariance, battery state), the quadrotor FMU is
built from it, the model's discrepancy is learned from replays of the training flights
(``identification.validation.workflow.learn_discrepancy``) and the held-out flight is replayed with Monte Carlo
bands (parameters + discrepancy + noise, ``validate_mc``). Pooled over the folds, per signal: the share of the
held-out logged samples inside the nominal 90 % band (target 80-95 % for every gated signal) and the band's mean
width over the replay's RMSE (target <= 3).

The shared fixed-wing excitation log has no second flight: its excitation blocks are split in time, the
discrepancy of the fixed-wing FMU is learned on the first half of the blocks and the bands are scored on the
held-out second half (same targets). The FMU is the project's default fixed wing (the log's derivatives are not
given): the bands must then carry a large model error, which is what they are for.

    .venv/bin/python bench/prediction_bands.py [--draws N] [--only erle,px4,wing]   # exit 1 on a miss

Heavy (minutes): every fold builds an FMU and runs N Monte Carlo replays on two local worker processes.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
ERLE = tuple(DATA / "quadrotor" / f"arducopter_x_quad_real_{n}.BIN" for n in (218, 104, 105))
PX4 = ((DATA / "quadrotor_px4_csv" / "drone1-8", 1.32), (DATA / "quadrotor_px4_csv" / "drone1-10", 1.085))
PX4_FMU_MASS_KG = 1.2
WING = DATA / "fixed_wing" / "arduplane_sitl_fmu_excitation.BIN"
WING_TIMELINE = DATA / "fixed_wing" / "arduplane_sitl_fmu_excitation.timeline.json"
COVERAGE = (0.80, 0.95)  #: pooled share of held-out samples inside the nominal 90 % band
MAX_WIDTH_OVER_RMSE = 3.0
#: the PX4 csv logs carry no altitude: their output map is the default without it
PX4_MAP = """[signals_extra]
[thresholds]
"""


@dataclass
class Pool:
    """Per signal, over folds: samples inside the band, samples scored, sum of widths, sum of squared errors."""

    inside: dict[str, int] = field(default_factory=dict)
    n: dict[str, int] = field(default_factory=dict)
    width: dict[str, float] = field(default_factory=dict)
    sse: dict[str, float] = field(default_factory=dict)
    gated: dict[str, bool] = field(default_factory=dict)

    def add(self, res: object) -> None:
        for m in res.maps:  # type: ignore[attr-defined]
            y, mod = res.measured[m.fmu], res.model[m.fmu]  # type: ignore[attr-defined]
            lo, hi = res.bands.lo[m.fmu], res.bands.hi[m.fmu]  # type: ignore[attr-defined]
            ok = np.isfinite(y) & np.isfinite(mod) & np.isfinite(lo) & np.isfinite(hi)
            k = m.fmu
            self.inside[k] = self.inside.get(k, 0) + int(((y[ok] >= lo[ok]) & (y[ok] <= hi[ok])).sum())
            self.n[k] = self.n.get(k, 0) + int(ok.sum())
            self.width[k] = self.width.get(k, 0.0) + float((hi[ok] - lo[ok]).sum())
            e = y[ok] - mod[ok]
            if m.wrap:
                e = (e + math.pi) % (2 * math.pi) - math.pi
            self.sse[k] = self.sse.get(k, 0.0) + float((e * e).sum())
            self.gated[k] = m.gate

    def table(self, title: str) -> bool:
        print(f"\n{title}: nominal 90 % bands, pooled over the held-out sets")
        print(f"  {'signal':<18} {'samples':>8} {'coverage':>9} {'mean width':>11} {'RMSE':>9} {'width/RMSE':>10}"
              "  target")
        ok = True
        for k in self.n:
            n = max(self.n[k], 1)
            cov, width, rmse = self.inside[k] / n, self.width[k] / n, math.sqrt(self.sse[k] / n)
            ratio = width / rmse if rmse > 0 else math.inf
            met = COVERAGE[0] <= cov <= COVERAGE[1] and ratio <= MAX_WIDTH_OVER_RMSE
            if self.gated[k]:
                ok &= met
            verdict = ("met" if met else "MISSED") if self.gated[k] else "not gated"
            print(f"  {k:<18} {self.n[k]:>8} {cov:>9.1%} {width:>11.4g} {rmse:>9.4g} {ratio:>10.2f}  {verdict}")
        return ok


def _fold(train: list[tuple[Path, float]], test: Path, work: Path, draws: int, fmu_mass: float | None,
          output_map: Path | None) -> object:
    from build_fmus import build
    from fmu_models.common.params import read_uncertainty
    from identification.thrust.workflow import FlightSpec, ThrustConfig, identify_thrust
    from identification.validation.discrepancy import read_discrepancy
    from identification.validation.workflow import ValidationJob, learn_discrepancy, validate_mc

    params = work / "params.json"
    r = identify_thrust(ThrustConfig(flights=tuple(FlightSpec(p, m) for p, m in train), out=params,
                                     fmu_mass_kg=fmu_mass, write_losing_model=True))
    print(f"  fold without {test.name}: thrust {r.spec.describe()}, verdict {r.verdict}")
    (fmu,) = build(params, work / "fmu", ["quadrotor"])
    job = ValidationJob(fmu, train[0][0], output_map=output_map, params_file=params)
    learn_discrepancy(job, [p for p, _ in train], params)
    res = validate_mc(ValidationJob(fmu, test, output_map=output_map, params_file=params), read_uncertainty(params),
                      draws, workers=2, discrepancy=read_discrepancy(params)).replay
    return res


def quadrotor(name: str, flights: list[tuple[Path, float]], draws: int, fmu_mass: float | None,
              output_map: Path | None) -> bool:
    pool = Pool()
    for i, (test, _) in enumerate(flights):
        train = [f for j, f in enumerate(flights) if j != i]
        with tempfile.TemporaryDirectory() as tmp:
            pool.add(_fold(train, test, Path(tmp), draws, fmu_mass, output_map))
    return pool.table(f"{name} leave-one-flight-out")


def fixed_wing(draws: int) -> bool:
    """Discrepancy learned on the first half of the excitation blocks, bands scored on the second half."""
    from build_fmus import build
    from fmu_models.common.params import Uncertainty
    from identification.validation.discrepancy import learn
    from identification.validation.workflow import ValidationJob, validate, validate_mc

    blocks = json.loads(WING_TIMELINE.read_text())["blocks"]
    spans = [(float(b["manual_start_s"]), float(b["manual_end_s"])) for b in blocks]
    half = len(spans) // 2
    with tempfile.TemporaryDirectory() as tmp:
        (fmu,) = build(None, Path(tmp), ["fixed_wing"])
        learned = [validate(ValidationJob(fmu, WING, t_range=s)).replay for s in spans[:half]]
        disc = learn(learned, [f"{WING.name} {a:.1f}-{b:.1f} s" for a, b in spans[:half]])
        # no identified covariance for the default fixed wing: one parameter with a negligible spread keeps the
        # Monte Carlo machinery (restart states, discrepancy) and adds no parameter uncertainty that is not there
        unc = Uncertainty(names=["mass_kg"], mean=[13.5], covariance=[[1e-12]])
        pool = Pool()
        for s in spans[half:]:
            pool.add(validate_mc(ValidationJob(fmu, WING, t_range=s), unc, draws, workers=2,
                                 discrepancy=disc).replay)
    return pool.table(f"fixed-wing excitation, blocks {half + 1}..{len(spans)} held out")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=19, help="Monte Carlo draws per replay (19: the fewest a 5-95 %% "
                    "band allows)")
    ap.add_argument("--only", default="erle,px4,wing", help="which studies (comma separated)")
    args = ap.parse_args()
    if not all(p.exists() for p in [*ERLE, *(p for p, _ in PX4), WING]):
        print(f"bench/prediction_bands.py: needs {DATA} (../shared/data beside the checkout)")
        return 2
    only = set(args.only.split(","))
    ok = True
    if "erle" in only:
        ok &= quadrotor("Erle", [(p, 1.14) for p in ERLE], args.draws, None, None)
    if "px4" in only:
        with tempfile.TemporaryDirectory() as tmp:
            omap = Path(tmp) / "px4_map.toml"
            omap.write_text(PX4_MAP)
            ok &= quadrotor("PX4 csv", list(PX4), args.draws, PX4_FMU_MASS_KG, omap)
    if "wing" in only:
        ok &= fixed_wing(args.draws)
    print(f"\nall targets: {'met' if ok else 'NOT met'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
