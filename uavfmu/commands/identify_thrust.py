"""``uavfmu identify thrust LOG[=MASS_KG] ...``: parse, call :func:`identification.thrust.workflow.identify_thrust`,
print the per-flight summaries and the held-out table.

Exit status: 0 no baseline beats the model on held-out data (the verdict says win or tie), 2 bad input, 3 a
baseline beats the model (the parameter file is then written only with ``--write-losing-model``; the exit
status stays 3). ``--method paper`` runs paper 000's single-log workflow instead (Pearson gate, ANFIS of summed
PWM; :func:`identification.thrust.paper.identify_thrust_paper`), exit 3 there = gate refused (unless
``--skip-pearson-gate``), or a baseline beats the model on the validation data. ``--accept-damaged-log`` uses
a log damaged beyond the limit. Every override is printed (``override: ...``) and listed in the metrics.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fmu_models.quadrotor.constants import PWM_IDLE_US

if TYPE_CHECKING:
    from identification.thrust.dataset import ThrustDataset
    from identification.thrust.paper import PaperThrustConfig, PaperThrustResult

EXIT_OK = 0
EXIT_BAD_INPUT = 2
EXIT_LOSES = 3
EXIT_GATE_REFUSED = 3  #: --method paper: the Pearson gate refused the data
#: options whose default differs between the two methods: (voltage workflow, paper workflow)
METHOD_DEFAULTS = {
    "mfs": (3, 3),
    "order": (1, 1),
    "epochs": (30, 100),
    "pwm_idle_us": (1000.0, PWM_IDLE_US),
    "pwm_max_us": (2000.0, 1900.0),
    "check_block_s": (5.0, 5.0),
}


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Options of ``identify thrust`` (both methods)."""
    p.add_argument("logs", nargs="+", metavar="LOG[=MASS_KG]",
                   help="flight logs of one vehicle (.BIN, .ulg, .tlog, a ulog2csv folder), each with its mass")
    p.add_argument("--mass", "--mass-kg", dest="mass_kg", type=float, help="mass [kg] of flights without =MASS")
    p.add_argument("--out", type=Path, required=True, help="parameter JSON to write")
    p.add_argument("--metrics", type=Path, help="metrics JSON (default: OUT with suffix .metrics.json)")
    p.add_argument("--method", choices=("voltage", "paper"), default="voltage",
                   help="voltage: per-motor voltage-aware model with cross-validation (default); paper: paper "
                   "000's single-log ANFIS of summed PWM with the Pearson gate")
    p.add_argument("--accept-damaged-log", action="store_true",
                   help="use a log whose damaged or lost share exceeds 5 %% (the damage is still reported)")
    p.add_argument("--write-losing-model", action="store_true",
                   help="write the parameter file even when a baseline beats the model (exit status stays 3)")
    p.add_argument("--channel-map", type=Path, help="TOML/JSON [channels] overriding the log's motor mapping")
    v = p.add_argument_group("voltage method")
    v.add_argument("--calibrate", choices=("auto", "on", "off"), default="auto",
                   help="per-flight hover calibration scale (auto: when no battery voltage is logged)")
    v.add_argument("--no-voltage", action="store_true", help="ignore logged battery voltage")
    v.add_argument("--no-battery-state", action="store_true",
                   help="without voltage: no hover-condition battery state (equivalent battery_voltage_V)")
    v.add_argument("--fmu-mass-kg", type=float,
                   help="the FMU's mass_kg [kg]; required when the flights' masses differ")
    v.add_argument("--vertical-drag-n-s-m", type=float, dest="vertical_drag_N_s_m",
                   help="known vertical drag coefficient kd_z [N s/m] (e.g. from identify quadrotor): the measured "
                   "thrust is -m a_z - kd_z w, w the body-z velocity (needs logged velocity and attitude)")
    v.add_argument("--folds", type=int, default=3, help="time blocks when a single flight is given (3)")
    v.add_argument("--jobs", type=int, help="cross-validation folds on N local worker processes (default: in this "
                   "process, no cluster start-up; 0..64)")
    v.add_argument("--scheduler", help="run the folds on the dask cluster at tcp://HOST:PORT (default: "
                   "$UAVFMU_SCHEDULER when set); see docs/scale-out.md")
    g = p.add_argument_group("data set and ANFIS (both methods)")
    g.add_argument("--lowpass-hz", type=float, help="zero-phase low-pass cut-off [Hz] (default: none)")
    g.add_argument("--max-lag-s", type=float, default=0.3, help="accelerometer lag search range +- [s] (0.3)")
    g.add_argument("--motor-min-pwm-us", type=float, default=1150.0,
                   help="airborne only with motor PWM above this [us] (voltage: the mean; paper: every motor)")
    g.add_argument("--mfs", type=int, help="ANFIS MFs (voltage: most rules tried, picked by inner CV, 3; paper 3)")
    g.add_argument("--epochs", type=int, help="hybrid-learning epochs (voltage 30, paper 100)")
    g.add_argument("--check-block-s", type=float, help="checking data: every 5th block of this length [s] (5)")
    g.add_argument("--pwm-idle-us", type=float, help="per-motor PWM of zero thrust [us] (voltage 1000, paper 1100)")
    g.add_argument("--pwm-max-us", type=float, help="per-motor PWM of full throttle [us] (voltage 2000, paper 1900)")
    _paper_arguments(p.add_argument_group("paper method only"))


def _paper_arguments(a: Any) -> None:
    from identification.thrust.dataset import PAPER_MIN_PEARSON

    a.add_argument("--validate", type=Path, help="second log for validation (default: the last part of LOG)")
    a.add_argument("--plots", type=Path, help="folder for the PNG figures (paper 000 Figs. 3-6)")
    a.add_argument("--train-fraction", type=float, default=0.7, help="first fraction to train on (0.7)")
    a.add_argument("--lag-s", type=float, help="accelerometer lag behind PWM [s] (default: estimated)")
    a.add_argument("--min-altitude-m", type=float, default=0.5, help="airborne only above this altitude [m]")
    a.add_argument("--extra-inputs", default="climb_rate_m_s,battery_voltage_V", help="extra candidate inputs")
    a.add_argument("--min-pearson", type=float, default=PAPER_MIN_PEARSON, help="Pearson gate (0.85)")
    a.add_argument("--skip-pearson-gate", action="store_true",
                   help="train even when r(summed PWM, F_z) is below the gate (recorded in the metrics)")
    a.add_argument("--mf-type", choices=("gaussian", "gbell"), default="gaussian")
    a.add_argument("--order", type=int, choices=(0, 1), help="Takagi-Sugeno order (1; paper 000 used 0)")
    a.add_argument("--step-size", type=float, default=0.01, help="initial gradient step kappa (0.01)")
    a.add_argument("--kv-rpm-per-V", type=float, default=920.0, help="motor Kv [rpm/V] (920)")
    a.add_argument("--battery-V", type=float, help="battery voltage [V] for k (default: logged median or 11.1)")
    a.add_argument("--k-thrust-N-s2", type=float, help="use this k instead of deriving it")


def _error(message: str) -> int:
    print(f"uavfmu identify thrust: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def parse_flights(items: list[str], default_mass: float | None) -> list[tuple[Path, float]]:
    """``LOG[=MASS_KG]`` items -> (path, mass); ValueError naming the flight when a mass is missing/bad."""
    out = []
    for item in items:
        path, mass_text = item, None
        if "=" in item and not Path(item).exists():
            path, mass_text = item.rsplit("=", 1)
        if mass_text is None:
            if default_mass is None:
                raise ValueError(f"flight {path}: no mass (give {path}=MASS_KG or --mass)")
            mass = default_mass
        else:
            try:
                mass = float(mass_text)
            except ValueError:
                raise ValueError(f"flight {path}: mass = {mass_text!r} is not a number [kg]") from None
        out.append((Path(path), mass))
    return out


def _defaults(args: argparse.Namespace) -> None:
    k = 0 if args.method == "voltage" else 1
    for name, values in METHOD_DEFAULTS.items():
        if getattr(args, name, None) is None:
            setattr(args, name, values[k])


def run(args: argparse.Namespace) -> int:
    """Run ``identify thrust``; return the exit status."""
    _defaults(args)
    try:
        flights = parse_flights(args.logs, args.mass_kg)
    except ValueError as err:
        return _error(str(err))
    if args.method == "paper":
        return _run_paper(args, flights)
    return _run_voltage(args, flights)


def _run_paper(args: argparse.Namespace, flights: list[tuple[Path, float]]) -> int:
    from fmu_models.common.errors import ParameterError
    from identification.logs.flightlog import LogError
    from identification.thrust.anfis_train import AnfisTrainingError
    from identification.thrust.dataset import CorrelationGateError, ThrustDataError
    from identification.thrust.paper import identify_thrust_paper, load_paper_data

    if len(flights) != 1:
        return _error(f"--method paper takes one log, got {len(flights)}; use --validate for a second one")
    log, mass_kg = flights[0]
    if not (math.isfinite(mass_kg)):
        return _error(f"flight {log}: mass = {mass_kg}; allowed a finite number in [0.05, 50] kg")
    try:
        cfg = paper_config(args, log, mass_kg)
        data = load_paper_data(cfg)
        for note in data.full.notes:
            print(f"note: {note}", file=sys.stderr)
        print(correlation_table(data.correlations, cfg.min_pearson, data.full))
        result = identify_thrust_paper(cfg, data, on_warning=lambda w: print(f"warning: {w}", file=sys.stderr))
    except CorrelationGateError as err:
        print(f"uavfmu identify thrust: refused: {err}", file=sys.stderr)
        return EXIT_GATE_REFUSED
    except (ThrustDataError, AnfisTrainingError, ParameterError, FileNotFoundError, LogError) as err:
        return _error(str(err))
    print(paper_summary(result))
    _print_overrides(result.overrides)
    if result.outcome == "lose":
        tail = "" if result.written else f"; {args.out} not written (--write-losing-model writes it)"
        print(f"uavfmu identify thrust: MODEL LOSES to a baseline on validation data (exit 3{tail})", file=sys.stderr)
    return result.exit_code


def _print_overrides(overrides: Any) -> None:
    for o in overrides:
        print(f"override: {o}", file=sys.stderr)


def paper_config(args: argparse.Namespace, log: Path, mass_kg: float) -> PaperThrustConfig:
    """The :class:`identification.thrust.paper.PaperThrustConfig` of the parsed options (errors as raised)."""
    from identification.thrust.anfis_train import AnfisTrainConfig
    from identification.thrust.dataset import ThrustDatasetConfig
    from identification.thrust.paper import PaperThrustConfig

    dataset = ThrustDatasetConfig(
        mass_kg=mass_kg, motor_min_pwm_us=args.motor_min_pwm_us, min_altitude_m=args.min_altitude_m,
        lag_s=args.lag_s, max_lag_s=args.max_lag_s, lowpass_hz=args.lowpass_hz,
        extra_inputs=tuple(s.strip() for s in args.extra_inputs.split(",") if s.strip()),
        pwm_idle_us=args.pwm_idle_us,
    )
    anfis = AnfisTrainConfig(n_mfs=args.mfs, mf_type=args.mf_type, order=args.order, epochs=args.epochs,
                             step_size=args.step_size, progress=True)
    return PaperThrustConfig(
        log=log, out=args.out, dataset=dataset, anfis=anfis, validate=args.validate, plots=args.plots,
        channel_map=args.channel_map, metrics=args.metrics, train_fraction=args.train_fraction,
        min_pearson=args.min_pearson, skip_gate=args.skip_pearson_gate, accept_damaged_log=args.accept_damaged_log,
        write_losing_model=args.write_losing_model, check_block_s=args.check_block_s,
        kv_rpm_per_V=args.kv_rpm_per_V, battery_V=args.battery_V, pwm_max_us=args.pwm_max_us,
        k_thrust_N_s2=args.k_thrust_N_s2,
    )


def correlation_table(corr: dict[str, float], gate: float, ds: ThrustDataset) -> str:
    """Pearson r of each candidate input with F_z, the gate's verdict on summed PWM, the lag used."""
    lag = f"{ds.lag_s * 1000:.0f} ms ({'estimated' if ds.lag_estimated else 'given'})"
    lines = [
        f"{ds.source}: {ds.n_samples} airborne samples, accelerometer lag {lag}",
        f"  {'candidate input':<22} {'Pearson r with F_z':>18}",
    ]
    for name, r in corr.items():
        mark = "" if name != "pwm_sum_us" else ("  (gate passed)" if r >= gate else f"  (below gate {gate:.2f})")
        lines.append(f"  {name:<22} {r:>18.3f}{mark}")
    return "\n".join(lines)


def paper_summary(result: PaperThrustResult) -> str:
    """Two-column summary of a :class:`identification.thrust.paper.PaperThrustResult`."""
    m = result.metrics
    polys = ", ".join(f"deg {d}: {v:.3f}" for d, v in m["polynomial_validation_rmse_N"].items())
    rows = [
        ("samples train / validation", f"{m['n_train']} / {m['n_validation']}"),
        ("epochs (kept)", f"{m['epochs']} ({m['best_epoch']})"),
        ("train RMSE [N], R^2", f"{m['train_rmse_N']:.3f}, {m['train_r2']:.3f}"),
        ("validation RMSE [N], R^2", f"{m['validation_rmse_N']:.3f}, {m['validation_r2']:.3f} (as the FMU evaluates)"),
        ("polynomial val. RMSE [N]", polys),
        ("constant m g val. RMSE [N]", f"{m['constant_validation_rmse_N']:.3f}"),
        ("verdict", m["verdict"]),
        ("trained band [us]", f"{m['band_us'][0]:.0f} .. {m['band_us'][1]:.0f}"),
        ("k_thrust [N s^2]", f"{result.k_thrust_N_s2:.4g}"),
        ("parameters", str(result.params_path)),
        ("metrics", str(result.metrics_path)),
    ]
    width = max(len(r[0]) for r in rows)
    return "\n".join(f"  {a:<{width}}  {b}" for a, b in rows)


def _run_voltage(args: argparse.Namespace, flights: list[tuple[Path, float]]) -> int:
    from fmu_models.common.errors import ParameterError
    from identification.common.parallel import ParallelError
    from identification.logs.flightlog import LogError
    from identification.thrust.anfis_train import AnfisTrainingError
    from identification.thrust.dataset import ThrustDataError
    from identification.thrust.workflow import FlightSpec, ThrustConfig, identify_thrust

    cfg = ThrustConfig(
        flights=tuple(FlightSpec(p, m) for p, m in flights), out=args.out, metrics=args.metrics,
        pwm_idle_us=args.pwm_idle_us, pwm_max_us=args.pwm_max_us, use_voltage=not args.no_voltage,
        calibrate=args.calibrate, n_mfs=args.mfs, epochs=args.epochs, n_folds_single=args.folds,
        motor_min_pwm_us=args.motor_min_pwm_us, max_lag_s=args.max_lag_s, lowpass_hz=args.lowpass_hz,
        check_block_s=args.check_block_s, channel_map=args.channel_map, fmu_mass_kg=args.fmu_mass_kg,
        battery_state=not args.no_battery_state, accept_damaged_log=args.accept_damaged_log,
        write_losing_model=args.write_losing_model, workers=args.jobs, scheduler=args.scheduler,
        vertical_drag_N_s_m=args.vertical_drag_N_s_m,
    )
    try:
        result = identify_thrust(cfg)
    except (ThrustDataError, AnfisTrainingError, ParameterError, LogError, FileNotFoundError,
            ParallelError) as err:
        return _error(str(err))
    print(format_report(result))
    for f in result.flights:
        for note in [*f["reader_warnings"], *f["notes"]]:
            print(f"note: flight {f['flight']}: {note}", file=sys.stderr)
    for w in result.warnings:
        print(f"warning: {w}", file=sys.stderr)
    _print_overrides(result.overrides)
    if result.verdict == "lose":
        print("uavfmu identify thrust: MODEL LOSES to a baseline on held-out data (exit 3)", file=sys.stderr)
    return result.exit_code


def format_report(r: Any) -> str:
    """Per-flight summaries, the held-out table (RMSE [N] / R^2 per predictor), the comparisons, the verdict."""
    lines = ["flights:"]
    for f in r.flights:
        v = f["voltage_range_V"]
        volt = f"{v[0]:.2f}..{v[1]:.2f} V" if v else "no voltage"
        lines.append(
            f"  {f['flight']}: {f['mass_kg']} kg, {f['samples']} samples, summed PWM "
            f"{f['pwm_sum_band_us'][0]:.0f}..{f['pwm_sum_band_us'][1]:.0f} us, {volt}, hover PWM "
            f"{f['hover_pwm_mean_us']:.0f} us, mean -m a_z {f['mean_thrust_N']:.2f} N (m g {f['weight_N']:.2f})"
        )
    names = list(r.pooled)
    head = ["held-out", "n", *names]
    rows = []
    for f in r.folds:
        scores = {"model": f.model, **f.baselines}
        rows.append([f.held_out, str(f.n_samples), *(f"{scores[k].rmse_N:.3f} / {scores[k].r2:.2f}" for k in names)])
    rows.append(["pooled RMSE", str(sum(f.n_samples for f in r.folds)), *(f"{r.pooled[k]:.3f}" for k in names)])
    lines.append(f"held-out thrust RMSE [N] / R^2 ({r.metrics.get('cross_validation')}; model = the FMU's thrust "
                 "with its battery state):")
    for i in range(0, len(names), 4):  # at most four predictors per block keeps the lines readable
        cols = [0, 1, *range(2 + i, min(2 + i + 4, len(head)))]
        block = [[row[c] for c in cols] for row in [head, *rows]]
        widths = [max(len(x[k]) for x in block) for k in range(len(cols))]
        lines += ["  " + "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)) for row in block]
    lines.append("skill = 1 - RMSE_model / RMSE_baseline, 90 % block-bootstrap interval (pooled; per held-out); "
                 "every pair has the same side information:")
    levels = list(dict.fromkeys(c["information"] for c in r.comparisons.values()))
    for level in levels:
        same = {k: c for k, c in r.comparisons.items() if c["information"] == level}
        judged = next(iter(same.values()))["in_verdict"]
        lines.append(f"  [{level}] {next(iter(same.values()))['information_text']}"
                     f"{'' if judged else ' (reported, not in the verdict)'}:")
        for key, c in same.items():
            p = c["pooled"]
            per = ", ".join(f"{h} {o['outcome']}" for h, o in c["per_held_out"].items())
            lines.append(f"    {key}: RMSE ratio {c['rmse_ratio']:.3f}, skill {p['skill']:+.3f} "
                         f"[{p['skill_lo']:+.3f}, {p['skill_hi']:+.3f}] {p['outcome'].upper()} ({per})")
    h = r.metrics.get("headline")
    if h:
        lines.append(f"headline (like for like, {h['information']}): {h['model']} {r.pooled[h['model']]:.3f} N vs "
                     f"{h['baseline']} {r.pooled[h['baseline']]:.3f} N pooled = {h['rmse_ratio']:.3f}x "
                     f"({h['outcome']})")
    lines.append(f"model: {r.spec.describe()}")
    if r.calibration:
        lines.append("per-flight calibration scale (thrust_scale for replays that do not drive the battery state): "
                     + ", ".join(f"{k} {v:.4f}" for k, v in r.calibration.items()))
    lines.append(f"verdict: {r.metrics.get('verdict_text')}")
    return "\n".join(lines)
