"""Benchmark: do the prediction bands of ``validate --mc`` cover flights they were not learned on?

Leave-one-flight-out on the shared quadrotor flights (three Erle, two PX4 csv): per fold, ``identify thrust`` on
the training flights writes the parameter file (thrust map, covariance, battery state), the quadrotor FMU is
built from it, the model's discrepancy is learned from replays of the training flights and calibrated on their
parameter draws (``identification.validation.workflow.learn_discrepancy_jobs``), and the held-out flight is
replayed with Monte Carlo bands (parameters + discrepancy, ``validate_mc``). Every flight is replayed at its own
mass (the one ``identify thrust`` is given). Pooled over the folds, per signal: the share of the held-out logged
samples inside the nominal 90 % band (target 80-95 % for every gated signal) and the band's mean width over the
replay's RMSE (target <= 3), beside the RMSE of persistence (the logged value at each window start held, the
replay's baseline, on the same samples) and the oracle's: the width over RMSE of a band made of the held-out residuals'
own 5-95 % quantiles per horizon bin (what a calibrated band of this form can at best reach; not a target).
Beside each pooled coverage, its one-sided 95 % bounds over the replay windows of every held-out set
(``mc_bands.coverage_bounds``, what ``validate --mc`` decides a finding with): where the target's end lies inside
them, the windows cannot tell the coverage from the target (the target is still judged on the point figure).
Per fold it prints the form each signal's band took (scale basis, sign, parameter weight, band factor), and with
``--per-set`` each held-out set's own coverage, width, RMSE and mean residual (logged - FMU) per signal
(where a pooled figure comes from).

The shared fixed-wing excitation log has no second flight: ``identify aero`` on it (the timeline's fit and
held-out segments, every default) writes the estimate and its covariance, the fixed-wing FMU is built from it,
and each held-out segment is scored with the discrepancy learned and calibrated on the other held-out segments
(``--wing-learn-on fit``: on the fit segments; ``all``: on both), same targets. ``wing-each``: every segment of the
log, fit and held-out, left out in turn (``identify aero`` on the others, the segment replayed with that estimate;
``identification.validation.cross_fit``, what ``identify aero --discrepancy`` stores) and scored with the
discrepancy learned and calibrated on the other segments' out-of-sample replays: ten identifications.

    .venv/bin/python bench/prediction_bands.py [--draws N] [--only erle,px4,wing,wing-each] [--no-parameter-spread]
        [--forms auto|unscaled] [--weight auto|1|0] [--per-set] [--start-velocity force|logged]
    # exit 1 on a miss

Heavy (minutes; tens of minutes on a loaded 2-core machine): every fold builds an FMU and runs N Monte Carlo
replays of each learning and held-out log, all on one local cluster of two worker processes.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
ERLE = tuple(DATA / "quadrotor" / f"arducopter_x_quad_real_{n}.BIN" for n in (218, 104, 105))
PX4 = ((DATA / "quadrotor_px4_csv" / "drone1-8", 1.32), (DATA / "quadrotor_px4_csv" / "drone1-10", 1.085))
PX4_FMU_MASS_KG = 1.2
WING = DATA / "fixed_wing" / "arduplane_sitl_fmu_excitation.BIN"
WING_TIMELINE = DATA / "fixed_wing" / "arduplane_sitl_fmu_excitation.timeline.json"
#: ``--wing-learn-on``: which segments a held-out segment's discrepancy is learned on
LEARN_ON = {"held": "other held-out segments", "fit": "fit segments",
            "all": "other held-out and fit segments"}
COVERAGE = (0.80, 0.95)  #: pooled share of held-out samples inside the nominal 90 % band
MAX_WIDTH_OVER_RMSE = 3.0


def px4_map_toml() -> str:
    """The quadrotor's default output map without ``altitude_m`` (the PX4 csv logs carry no altitude)."""
    from identification.validation.output_map import QUADROTOR

    lines = []
    for m in QUADROTOR:
        if m.fmu == "altitude_m":
            continue
        lines += [f"[signals.{m.fmu}]", f'log = "{m.log}"', f"scale = {m.scale}", f"wrap = {str(m.wrap).lower()}"]
        lines += [f'scale_by_param = "{m.scale_by_param}"'] if m.scale_by_param else []
        lines += [f"max_rmse = {m.max_rmse}"] if m.max_rmse is not None else []
    return "\n".join(lines) + "\n"


@dataclass
class Pool:
    """Per signal, over folds: samples inside the band, samples scored, sum of widths, sum of squared errors."""

    inside: dict[str, int] = field(default_factory=dict)
    n: dict[str, int] = field(default_factory=dict)
    width: dict[str, float] = field(default_factory=dict)
    sse: dict[str, float] = field(default_factory=dict)
    #: squared errors of persistence (the logged value at the window start held) on the same samples: the baseline
    sse_persistence: dict[str, float] = field(default_factory=dict)
    gated: dict[str, bool] = field(default_factory=dict)
    #: per signal: (residual, horizon [s]) arrays of every held-out set, for the oracle width
    kept: dict[str, list[tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)
    #: per signal: (inside, window id, position in the band) arrays of every held-out set, for the coverage's bounds
    windows: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = field(default_factory=dict)
    #: print each held-out set's own figures as it is added
    per_set: bool = False

    def add(self, res: object) -> None:
        from identification.validation.discrepancy import horizons_s, window_index
        from identification.validation.mc_bands import band_position, inside_band

        if self.per_set:
            print(f"    {'this set':<18} {'samples':>8} {'coverage':>9} {'mean width':>11} {'RMSE':>9} "
                  f"{'width/RMSE':>10} {'pers. RMSE':>10} {'mean resid':>10}")
        for m in res.maps:  # type: ignore[attr-defined]
            y, mod = res.measured[m.fmu], res.model[m.fmu]  # type: ignore[attr-defined]
            lo, hi = res.bands.lo[m.fmu], res.bands.hi[m.fmu]  # type: ignore[attr-defined]
            pers = res.persistence[m.fmu]  # type: ignore[attr-defined]
            ok = np.isfinite(y) & np.isfinite(mod) & np.isfinite(lo) & np.isfinite(hi) & np.isfinite(pers)
            k = m.fmu
            self.inside[k] = self.inside.get(k, 0) + int(inside_band(y[ok], lo[ok], hi[ok], m.wrap).sum())
            self.n[k] = self.n.get(k, 0) + int(ok.sum())
            width = hi[ok] - lo[ok]
            self.width[k] = self.width.get(k, 0.0) + float(np.minimum(width, 2 * math.pi if m.wrap else np.inf).sum())
            e = y[ok] - mod[ok]
            if m.wrap:
                e = (e + math.pi) % (2 * math.pi) - math.pi
            self.sse[k] = self.sse.get(k, 0.0) + float((e * e).sum())
            ep = y[ok] - pers[ok]
            if m.wrap:
                ep = (ep + math.pi) % (2 * math.pi) - math.pi
            self.sse_persistence[k] = self.sse_persistence.get(k, 0.0) + float((ep * ep).sum())
            if self.per_set and e.size:
                cov = float(inside_band(y[ok], lo[ok], hi[ok], m.wrap).mean())
                w, rmse = float(np.minimum(width, 2 * math.pi if m.wrap else np.inf).mean()), math.sqrt(float(
                    np.mean(e * e)))
                print(f"    {k:<18} {e.size:>8} {cov:>9.1%} {w:>11.4g} {rmse:>9.4g} "
                      f"{w / rmse if rmse > 0 else math.inf:>10.2f} {math.sqrt(float(np.mean(ep * ep))):>10.4g} "
                      f"{float(np.mean(e)):>+10.4g}")
            self.gated[k] = m.gate
            self.kept.setdefault(k, []).append((e, horizons_s(res)[ok]))  # type: ignore[arg-type]
            sets = self.windows.setdefault(k, [])
            sets.append((inside_band(y[ok], lo[ok], hi[ok], m.wrap),
                         window_index(res)[ok] + 1_000_000 * len(sets),  # type: ignore[arg-type]
                         band_position(y[ok], lo[ok], hi[ok], m.wrap)))

    def oracle(self, k: str) -> float:
        """Mean width over RMSE of the band an oracle draws: the held-out residuals' own 5-95 % quantiles per
        horizon bin (``discrepancy.N_BINS`` equal bins), what a calibrated band of this form can at best reach."""
        from identification.validation.discrepancy import N_BINS

        e = np.concatenate([x for x, _ in self.kept[k]])
        h = np.concatenate([x for _, x in self.kept[k]])
        edges = np.linspace(0.0, float(h.max()) + 1e-9, N_BINS + 1)
        width = sum(int(sel.sum()) * float(np.subtract(*np.quantile(e[sel], [0.95, 0.05])))
                    for a, b in itertools.pairwise(edges) for sel in [(h >= a) & (h < b)] if sel.any())
        return width / e.size / math.sqrt(float(np.mean(e * e)))

    def bounds(self, k: str) -> str:
        """The pooled coverage's one-sided 95 % bounds over the held-out sets' windows, as ``[lower, upper]``."""
        from identification.validation.mc_bands import coverage_bounds

        parts = self.windows.get(k) or []
        if not parts:
            return "-"
        b = coverage_bounds(*(np.concatenate(x) for x in zip(*parts, strict=True)))
        return f"[{b.lower:.0%}, {b.upper:.0%}]"

    def table(self, title: str) -> bool:
        print(f"\n{title}: nominal 90 % bands, pooled over the held-out sets")
        print(f"  {'signal':<18} {'samples':>8} {'coverage':>9} {'95 % bounds':>12} {'mean width':>11} {'RMSE':>9} "
              f"{'width/RMSE':>10} {'oracle':>7} {'pers. RMSE':>10}  target")
        ok = True
        for k in self.n:
            n = max(self.n[k], 1)
            cov, width, rmse = self.inside[k] / n, self.width[k] / n, math.sqrt(self.sse[k] / n)
            ratio = width / rmse if rmse > 0 else math.inf
            met = COVERAGE[0] <= cov <= COVERAGE[1] and ratio <= MAX_WIDTH_OVER_RMSE
            if self.gated[k]:
                ok &= met
            verdict = ("met" if met else "MISSED") if self.gated[k] else "not gated"
            print(f"  {k:<18} {self.n[k]:>8} {cov:>9.1%} {self.bounds(k):>12} {width:>11.4g} {rmse:>9.4g} "
                  f"{ratio:>10.2f} {self.oracle(k):>7.2f} {math.sqrt(self.sse_persistence[k] / n):>10.4g}  {verdict}")
        return ok


def chosen(disc: object) -> str:
    """Per signal the band form a fold learned: the scale basis (``none``: unscaled), ``signed`` where the sign is
    kept, ``offset`` and its value where the band is centred on the restart's offset, the parameter weight and the
    band factor."""
    out = []
    for k, v in disc.signals.items():  # type: ignore[attr-defined]
        scale = v.scale_by if v.scale_floor is not None else "none"
        weight = 1.0 if v.parameter_weight is None else v.parameter_weight
        offset = "" if v.offset is None else f" offset {v.offset:+.3g}"
        out.append(f"{k} {scale}{'' if v.symmetric else ' signed'}{offset} w{weight:g} f{v.band_factor or 1.0:.2f}")
    return "    forms: " + ", ".join(out)


def _fold(train: list[tuple[Path, float]], test: tuple[Path, float], work: Path, draws: int,
          fmu_mass: float | None, output_map: Path | None, study: dict[str, Any]) -> object:
    """One fold: identify on ``train``, build, learn the discrepancy on replays of ``train``, score ``test``. Every
    flight is replayed at its own mass (``mass_kg``, the one ``identify thrust`` was given): the logged thrust is
    the specific force times that mass."""
    from build_fmus import build
    from fmu_models.common.params import read_uncertainty
    from identification.thrust.workflow import FlightSpec, ThrustConfig, identify_thrust
    from identification.validation.discrepancy import read_discrepancy
    from identification.validation.workflow import ValidationJob, learn_discrepancy_jobs, validate_mc

    params = work / "params.json"
    r = identify_thrust(ThrustConfig(flights=tuple(FlightSpec(p, m) for p, m in train), out=params,
                                     fmu_mass_kg=fmu_mass, write_losing_model=True))
    print(f"  fold without {test[0].name}: thrust {r.spec.describe()}, verdict {r.verdict}")
    (fmu,) = build(params, work / "fmu", ["quadrotor"])

    def job(log: Path, mass_kg: float) -> ValidationJob:
        return ValidationJob(fmu, log, output_map=output_map, params_file=params, start_values={"mass_kg": mass_kg})

    unc = read_uncertainty(params)
    learn_discrepancy_jobs([job(p, m) for p, m in train], params, unc, draws, **study)
    print(chosen(read_discrepancy(params)))
    return validate_mc(job(*test), unc, draws, executor=study["executor"],
                       discrepancy=read_discrepancy(params)).replay


def quadrotor(name: str, flights: list[tuple[Path, float]], draws: int, fmu_mass: float | None,
              output_map: Path | None, study: dict[str, Any], per_set: bool = False) -> bool:
    pool = Pool(per_set=per_set)
    for i, test in enumerate(flights):
        train = [f for j, f in enumerate(flights) if j != i]
        with tempfile.TemporaryDirectory() as tmp:
            pool.add(_fold(train, test, Path(tmp), draws, fmu_mass, output_map, study))
    return pool.table(f"{name} leave-one-flight-out")


def fixed_wing(draws: int, parameter_spread: bool = True, learn_on: str = "held",
               study: dict[str, Any] | None = None, per_set: bool = False, start_velocity: str = "force") -> bool:
    """``identify aero`` on the excitation log (its timeline's fit and held-out segments), the FMU built from the
    estimate, the bands scored on each held-out segment with the discrepancy learned on the other held-out segments
    (``learn_on`` "held": where the truth is known and the parameters were not fitted; leave-one-segment-out so no
    segment is scored by what it taught), on the fit segments ("fit") or on both ("all": every kind of manoeuvre, the
    fit segments' residuals in-sample). ``start_velocity``: the replay windows'
    start body velocity (``ValidationOptions.start_velocity``)."""
    from build_fmus import build
    from fmu_models.common.params import Uncertainty, read_uncertainty
    from fmu_models.fixed_wing.params import FixedWingParams
    from fmu_models.signals.pwm_mapping import PwmMapping
    from identification.aero.identify import AeroOptions, AeroSource, identify_aero, write_results
    from identification.aero.model import parse_segments
    from identification.logs.readers import read_log
    from identification.validation.replay import options
    from identification.validation.workflow import ValidationJob, learn_discrepancy_jobs, validate_mc

    log = read_log(WING)
    with tempfile.TemporaryDirectory() as tmp:
        params = Path(tmp) / "excite.json"
        result = identify_aero([AeroSource(log, PwmMapping.from_ardupilot(log.params), None, None, None)], None,
                               FixedWingParams(), AeroOptions(free="auto", progress=False))
        write_results(result, params, Path(tmp) / "excite.metrics.json", WING.name, 50.0)
        metrics = json.loads((Path(tmp) / "excite.metrics.json").read_text())
        fit = [(g.t0_s, g.t1_s) for g in parse_segments(",".join(metrics["fit_segments"]))]
        held = [(g.t0_s, g.t1_s) for g in parse_segments(",".join(metrics["validation_segments"]))]
        print(f"  identify aero: {len(fit)} fit and {len(held)} held-out segments; discrepancy learned on the "
              + LEARN_ON[learn_on])
        (fmu,) = build(params, Path(tmp) / "fmu", ["fixed_wing"])

        def job(span: tuple[float, float]) -> ValidationJob:
            return ValidationJob(fmu, WING, options(start_velocity=start_velocity), t_range_s=span,
                                 embedded_params=False)

        unc = read_uncertainty(params)
        if not parameter_spread:  # a study: the discrepancy alone, the parameters at their estimate
            unc = Uncertainty(names=unc.names, mean=unc.mean, covariance=[[0.0] * len(unc.names)] * len(unc.names))
        pool = Pool(per_set=per_set)
        study = study or {}
        learned_on_fit = (learn_discrepancy_jobs([job(x) for x in fit], None, unc, draws, **study)
                          if learn_on == "fit" else None)
        for s in held:
            others = [x for x in held if x != s] + (fit if learn_on == "all" else [])
            learned = learned_on_fit or learn_discrepancy_jobs([job(x) for x in others], None, unc, draws, **study)
            print(f"  segment {s[0]:g}-{s[1]:g} s\n{chosen(learned.discrepancy)}")
            pool.add(validate_mc(job(s), unc, draws, executor=study["executor"],
                                 discrepancy=learned.discrepancy).replay)
    return pool.table(f"fixed-wing excitation log, held-out segments of identify aero (discrepancy from the "
                      f"{LEARN_ON[learn_on]}"
                      + (")" if parameter_spread else "; no parameter spread)"))


def fixed_wing_each(draws: int, study: dict[str, Any], per_set: bool = False, start_velocity: str = "force") -> bool:
    """Leave-one-segment-out over every segment of the excitation log's timeline, fit and held-out alike
    (``identification.validation.cross_fit``, what ``identify aero --discrepancy`` stores): per segment,
    ``identify aero`` on the others (every default) and the segment replayed with that estimate (its out-of-sample
    replay, with ``draws`` parameter draws from that fold's covariance). Each segment is then scored with the
    discrepancy learned and calibrated on the other segments' out-of-sample replays: three repetitions of each
    axis, every kind of manoeuvre, among the learning replays, which the timeline's three held-out segments (one
    per axis) cannot give."""
    from fmu_models.fixed_wing.params import FixedWingParams
    from fmu_models.signals.pwm_mapping import PwmMapping
    from identification.aero.identify import AeroOptions, AeroSource, identify_aero
    from identification.logs.readers import read_log
    from identification.validation.cross_fit import learn_folds, replay_fmu, segment_folds
    from identification.validation.replay import options
    from identification.validation.workflow import validate_mc

    log = read_log(WING)
    opt = AeroOptions(free="auto", progress=False)
    whole = identify_aero([AeroSource(log, PwmMapping.from_ardupilot(log.params), None, None, None)], None,
                          FixedWingParams(), opt)
    segments = sorted([*whole.fit_segments, *whole.validation_segments], key=lambda g: g.t0_s)
    print(f"  identify aero: {len(segments)} segments, each left out in turn; discrepancy learned on the others' "
          "out-of-sample replays")
    ex = study["executor"]
    with tempfile.TemporaryDirectory() as tmp:
        folds, skipped = segment_folds(WING, segments, replay_fmu(Path(tmp)), opt, FixedWingParams(), options(
            start_velocity=start_velocity), draws, executor=ex, progress=lambda m: print(f"    {m}"))
        for line in skipped:
            print(f"    skipped: {line}")
        pool = Pool(per_set=per_set)
        for i, f in enumerate(folds):
            disc = learn_folds(folds, exclude=i, scaled=study["scaled"], weights=study["weights"])
            print(f"  segment {f.segment.t0_s:g}-{f.segment.t1_s:g} s"
                  + (f" (its fold recorded: {'; '.join(f.failures)})" if f.failures else "") + f"\n{chosen(disc)}")
            pool.add(validate_mc(f.job, f.uncertainty, draws, executor=ex, discrepancy=disc).replay)
    return pool.table("fixed-wing excitation log, every segment left out in turn (identify aero and the "
                      "discrepancy on the others)") and not skipped


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=19, help="Monte Carlo draws per replay (19: the fewest a 5-95 %% "
                    "band allows)")
    ap.add_argument("--only", default="erle,px4,wing,wing-each", help="which studies (comma separated)")
    ap.add_argument("--no-parameter-spread", action="store_true",
                    help="fixed wing: the parameters at their estimate (a zero covariance), the discrepancy alone")
    ap.add_argument("--wing-learn-on", choices=("held", "fit", "all"), default="held",
                    help="fixed wing: learn the discrepancy on the other held-out segments (default), the fit ones, "
                         "or both (all)")
    ap.add_argument("--forms", choices=("auto", "unscaled"), default="auto",
                    help="a study: the band forms chosen on learning replays left out (auto), or unscaled only")
    ap.add_argument("--weight", choices=("auto", "1", "0"), default="auto",
                    help="a study: the parameter weight chosen on learning replays left out (auto), or always 1 "
                         "(the draws in every band), or always 0 (the discrepancy alone)")
    ap.add_argument("--per-set", action="store_true", help="also each held-out set's own figures per signal")
    ap.add_argument("--start-velocity", choices=("force", "logged"), default="force",
                    help="fixed wing: the replay windows' start body velocity from the specific force (default) or "
                         "the GPS as logged (validate --start-velocity)")
    args = ap.parse_args()
    study = {"scaled": args.forms == "auto",
             "weights": {"auto": (1.0, 0.0), "1": (1.0,), "0": (0.0,)}[args.weight]}
    if not all(p.exists() for p in [*ERLE, *(p for p, _ in PX4), WING]):
        print(f"bench/prediction_bands.py: needs {DATA} (../shared/data beside the checkout)")
        return 2
    from identification.common.parallel import Executor

    only = set(args.only.split(","))
    with Executor(workers=2) as ex:  # one local cluster for every Monte Carlo run (the draws do not depend on it)
        study["executor"] = ex
        ok = _studies(only, args, study)
    print(f"\nall targets: {'met' if ok else 'NOT met'}")
    return 0 if ok else 1


def _studies(only: set[str], args: argparse.Namespace, study: dict[str, Any]) -> bool:
    ok = True
    if "erle" in only:
        ok &= quadrotor("Erle", [(p, 1.14) for p in ERLE], args.draws, None, None, study, args.per_set)
    if "px4" in only:
        with tempfile.TemporaryDirectory() as tmp:
            omap = Path(tmp) / "px4_map.toml"
            omap.write_text(px4_map_toml())
            ok &= quadrotor("PX4 csv", list(PX4), args.draws, PX4_FMU_MASS_KG, omap, study, args.per_set)
    if "wing" in only:
        ok &= fixed_wing(args.draws, not args.no_parameter_spread, args.wing_learn_on, study, args.per_set,
                         args.start_velocity)
    if "wing-each" in only:
        ok &= fixed_wing_each(args.draws, study, args.per_set, args.start_velocity)
    return ok


if __name__ == "__main__":
    raise SystemExit(main())
