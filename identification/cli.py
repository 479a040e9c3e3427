"""Paper 000's single-log thrust workflow (``uavfmu identify thrust --method paper``) and the ``aero`` passthrough.

The command line lives in ``uavfmu.commands.identify`` / ``identify_thrust``; the default thrust workflow is
``identification.thrust_workflow``. ``run_thrust(args)`` here is the paper method: it cuts the
airborne (PWM, F_z) data set from LOG, reports the Pearson correlation of each candidate input with F_z,
refuses to train below the paper's 0.85 gate unless ``--force``, trains the ANFIS by hybrid learning,
scores it on validation data (LOG2, or the last part of LOG) against least-squares polynomials, derives
k of eq. 6 from the curve's slope and writes a parameter file ``build_fmus.py --params`` reads.
``aero`` is implemented in ``identification.aero_cli``, imported only when ``aero`` is used.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings
from pathlib import Path
from typing import Any

from identification.jsonio import write_json

EXIT_OK = 0
EXIT_BAD_INPUT = 2
EXIT_GATE_REFUSED = 3
CHECK_EVERY = 5  #: every 5th block of the training data is checking data (early stopping)


class _SubParser(argparse.ArgumentParser):
    """Sub-parser that, with ``passthrough=True``, hands all its arguments on unparsed (``rest_argv``).

    Lets ``aero`` forward its arguments to ``identification.aero_cli``'s own parser, so that module is
    imported only when ``aero`` runs.
    """

    def __init__(self, *args: Any, passthrough: bool = False, **kwargs: Any) -> None:
        self.passthrough = passthrough
        if passthrough:
            kwargs["add_help"] = False
        super().__init__(*args, **kwargs)

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        if not self.passthrough:
            return super().parse_known_args(args, namespace)
        ns = namespace if namespace is not None else argparse.Namespace()
        ns.rest_argv = list(args or [])
        return ns, []


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``thrust`` and ``aero`` sub-commands to ``parser``."""
    sub = parser.add_subparsers(dest="identify_what", required=True, parser_class=_SubParser)
    th = sub.add_parser("thrust", help="ANFIS thrust map F_z(summed PWM) of a quadrotor (paper 000)")
    _thrust_arguments(th)
    sub.add_parser(
        "aero", passthrough=True, help="fixed-wing aerodynamic derivatives (identification.aero_cli)"
    )


def _thrust_arguments(p: argparse.ArgumentParser) -> None:
    from identification.thrust_dataset import PAPER_MIN_PEARSON

    p.add_argument("log", type=Path, help="flight log (.BIN DataFlash, .ulg ULog, ...)")
    p.add_argument("--mass", "--mass-kg", dest="mass_kg", type=float, required=True, help="vehicle mass [kg]")
    p.add_argument("--out", type=Path, required=True, help="parameter JSON to write")
    p.add_argument("--validate", type=Path, help="second log for validation (default: the last part of LOG)")
    p.add_argument("--plots", type=Path, help="folder for the PNG figures (paper 000 Figs. 3-6)")
    p.add_argument("--channel-map", type=Path, help="TOML/JSON [channels] overriding the log's motor mapping")
    p.add_argument("--metrics", type=Path, help="metrics JSON (default: OUT with suffix .metrics.json)")
    g = p.add_argument_group("data set")
    g.add_argument(
        "--train-fraction",
        type=float,
        default=0.7,
        help="without --validate: first fraction of the airborne samples to train on (0.7)",
    )
    g.add_argument("--lowpass-hz", type=float, help="zero-phase low-pass cut-off [Hz] (default: none)")
    g.add_argument("--lag-s", type=float, help="accelerometer lag behind PWM [s] (default: estimated)")
    g.add_argument("--max-lag-s", type=float, default=0.3, help="lag search range +- [s] (0.3)")
    g.add_argument(
        "--motor-min-pwm-us",
        type=float,
        default=1150.0,
        help="airborne only with every motor above this PWM [us] (1150)",
    )
    g.add_argument(
        "--min-altitude-m",
        type=float,
        default=0.5,
        help="airborne only above this altitude over home [m], when logged (0.5)",
    )
    g.add_argument(
        "--extra-inputs",
        default="climb_rate_m_s,battery_voltage_V",
        help="comma-separated extra candidate inputs to report (used when logged)",
    )
    g.add_argument(
        "--min-pearson",
        type=float,
        default=PAPER_MIN_PEARSON,
        help=f"Pearson gate on r(summed PWM, F_z) ({PAPER_MIN_PEARSON}, paper 000)",
    )
    g.add_argument("--force", action="store_true", help="train even when the Pearson gate fails")
    a = p.add_argument_group("ANFIS")
    a.add_argument("--mfs", type=int, default=3, help="membership functions (3; paper 000 used 6)")
    a.add_argument("--mf-type", choices=("gaussian", "gbell"), default="gaussian")
    a.add_argument(
        "--order", type=int, choices=(0, 1), default=1, help="Takagi-Sugeno order (1; paper 000 used 0)"
    )
    a.add_argument("--epochs", type=int, default=100)
    a.add_argument("--step-size", type=float, default=0.01, help="initial gradient step kappa (0.01)")
    a.add_argument(
        "--check-block-s",
        type=float,
        default=5.0,
        help=f"checking data: every {CHECK_EVERY}th block of this length of the training data [s]",
    )
    k = p.add_argument_group("k of eq. 6 (motor speed model Omega = Kv V (pwm - idle) / (max - idle))")
    k.add_argument("--kv-rpm-per-V", type=float, default=920.0, help="motor Kv [rpm/V] (920)")
    k.add_argument(
        "--battery-V",
        type=float,
        help="battery voltage [V] (default: median logged battery_voltage_V, else 11.1)",
    )
    k.add_argument(
        "--pwm-idle-us", type=float, default=1100.0, help="per-motor PWM of zero thrust [us] (1100)"
    )
    k.add_argument(
        "--pwm-max-us", type=float, default=1900.0, help="per-motor PWM of full throttle [us] (1900)"
    )
    k.add_argument("--k-thrust-N-s2", type=float, help="use this k instead of deriving it")


def run(args: argparse.Namespace) -> int:
    """Run the chosen ``identify`` sub-command; return the exit status."""
    if args.identify_what == "aero":
        return _run_aero(getattr(args, "rest_argv", []))
    return run_thrust(args)


def _run_aero(argv: list[str]) -> int:
    module = importlib.import_module("identification.aero_cli")
    parser = argparse.ArgumentParser(prog="uavfmu identify aero")
    module.add_arguments(parser)
    return int(module.run(parser.parse_args(argv)) or 0)


def _error(message: str) -> int:
    print(f"uavfmu identify thrust: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _read(path: Path, channel_map: Path | None = None) -> Any:
    """The ``FlightLog`` of ``path`` (``identification.readers.read_log``)."""
    from identification.readers import read_log

    return read_log(path, channel_map=channel_map)


def run_thrust(args: argparse.Namespace) -> int:
    """``uavfmu identify thrust``; see the module docstring."""
    import numpy as np

    from fmu_models.common.errors import ParameterError
    from identification.anfis_train import AnfisTrainConfig, AnfisTrainingError
    from identification.flightlog import LogError
    from identification.thrust_dataset import (
        CorrelationGateError,
        ThrustDataError,
        ThrustDatasetConfig,
    )

    try:
        extra = tuple(s.strip() for s in args.extra_inputs.split(",") if s.strip())
        ds_cfg = ThrustDatasetConfig(
            mass_kg=args.mass_kg,
            motor_min_pwm_us=args.motor_min_pwm_us,
            min_altitude_m=args.min_altitude_m,
            lag_s=args.lag_s,
            max_lag_s=args.max_lag_s,
            lowpass_hz=args.lowpass_hz,
            extra_inputs=extra,
            pwm_idle_us=args.pwm_idle_us,
        )
        train_cfg = AnfisTrainConfig(
            n_mfs=args.mfs,
            mf_type=args.mf_type,
            order=args.order,
            epochs=args.epochs,
            step_size=args.step_size,
            progress=True,
        )
        if not 0.0 < args.train_fraction < 1.0:
            raise ThrustDataError(f"--train-fraction = {args.train_fraction}; allowed (0, 1)")
        if not -1.0 <= args.min_pearson <= 1.0:
            raise ThrustDataError(f"--min-pearson = {args.min_pearson}; allowed [-1, 1]")
        return _thrust(args, ds_cfg, train_cfg, np)
    except CorrelationGateError as err:
        print(f"uavfmu identify thrust: refused: {err}", file=sys.stderr)
        return EXIT_GATE_REFUSED
    except (ThrustDataError, AnfisTrainingError, ParameterError, FileNotFoundError, LogError) as err:
        return _error(str(err))


def _thrust(args: argparse.Namespace, ds_cfg: Any, train_cfg: Any, np: Any) -> int:
    import dataclasses

    from fmu_models.quadrotor.params import QuadrotorParams
    from identification import plots
    from identification.anfis_train import polynomial_baselines, predict, r_squared, rmse, train_anfis
    from identification.thrust_dataset import (
        CorrelationGateError,
        MotorSpeedModel,
        ThrustDataError,
        build_thrust_dataset,
        check_gate,
        interleaved_blocks,
        k_thrust_from_curve,
        pearson,
    )

    for path in (args.log, args.validate):
        if path is not None and not path.is_file():
            raise FileNotFoundError(f"{path}: log file not found")
    log = _read(args.log, args.channel_map)
    full = build_thrust_dataset(log, ds_cfg, source=str(args.log))
    for note in full.notes:
        print(f"note: {note}", file=sys.stderr)
    if args.validate is not None:
        train = full
        vcfg = dataclasses.replace(ds_cfg, lag_s=full.lag_s)
        val = build_thrust_dataset(_read(args.validate, args.channel_map), vcfg, source=str(args.validate))
        val_name = str(args.validate)
    else:
        train, val = full.split(args.train_fraction)
        val_name = f"last {1.0 - args.train_fraction:.0%} of {args.log.name}"
    corr = full.correlations()  # the gate looks at all airborne data of LOG, as the paper's Fig. 3
    print(_correlation_table(corr, args.min_pearson, full))
    metrics: dict[str, Any] = {
        "log": str(args.log),
        "validation": val_name,
        "mass_kg": args.mass_kg,
        "lag_s": full.lag_s,
        "lag_estimated": full.lag_estimated,
        "lowpass_hz": args.lowpass_hz,
        "pearson": corr,
        "pearson_train_split": train.correlations(),
        "pearson_gate": args.min_pearson,
        "n_train": train.n_samples,
        "n_validation": val.n_samples,
        "notes": list(full.notes),
    }
    metrics_path = args.metrics or args.out.with_suffix(".metrics.json")
    if args.plots:
        plots.thrust_correlation(
            args.plots / "fig3_correlation.png", full.pwm_sum_us, full.fz_N, corr, args.min_pearson
        )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # printed below instead
            gate_warnings = check_gate(
                corr, ("pwm_sum_us",), args.min_pearson, args.force, source=str(args.log)
            )
    except CorrelationGateError:
        metrics["refused"] = True
        write_json(metrics_path, metrics)
        raise
    metrics["gate_forced"] = bool(gate_warnings)
    if gate_warnings:
        print(f"warning: --force given; training despite the gate: {gate_warnings[0]}", file=sys.stderr)

    block = max(1, round(args.check_block_s / train.sample_period_s))
    chk = interleaved_blocks(train.n_samples, block, CHECK_EVERY)
    result = train_anfis(
        train.pwm_sum_us[~chk],
        train.fz_N[~chk],
        train_cfg,
        train.pwm_sum_us[chk],
        train.fz_N[chk],
        input_names=("pwm_sum_us",),
        output="thrust_N",
        source=f"uavfmu identify thrust {args.log.name} (hybrid ANFIS, {train_cfg.n_mfs} "
        f"{train_cfg.mf_type} MFs, "
        f"order {train_cfg.order})",
    )
    amap = result.amap
    y_val = predict(amap, val.pwm_sum_us)
    y_train = predict(amap, train.pwm_sum_us)
    polys = polynomial_baselines(train.pwm_sum_us, train.fz_N, val.pwm_sum_us, val.fz_N)
    best_poly = min(polys, key=lambda p: p.test_rmse)

    battery_V = args.battery_V
    if battery_V is None:
        bv = train.inputs.get("battery_voltage_V")
        battery_V = float(np.median(bv)) if bv is not None else 11.1
    motor = MotorSpeedModel(args.kv_rpm_per_V, battery_V, args.pwm_idle_us, args.pwm_max_us)
    given_k = args.k_thrust_N_s2
    try:
        kc = k_thrust_from_curve(amap, train.pwm_sum_us, motor)
    except ThrustDataError:
        if given_k is None:
            raise
        kc = None  # k given explicitly: the derivation is only a diagnostic
    if kc is not None:
        ratio = kc.k_N_s2 / kc.k_from_level_N_s2 if kc.k_from_level_N_s2 > 0.0 else float("inf")
        if not 0.5 <= ratio <= 2.0:
            print(
                f"warning: k from the curve's slope ({kc.k_N_s2:.3g}) and from its level "
                f"({kc.k_from_level_N_s2:.3g}) differ by {ratio:.2f}x: the motor speed model or the "
                "data's PWM-thrust slope is off (battery sag over a hover flight makes the slope shallow)",
                file=sys.stderr,
            )
    if given_k is not None:
        k_value, k_source = given_k, "given on the command line (--k-thrust-N-s2)"
    else:
        assert kc is not None  # derivation errors were raised above
        k_value, k_source = kc.k_N_s2, kc.description

    section = {
        "mass_kg": args.mass_kg,
        "pwm_idle_us": args.pwm_idle_us,
        "k_thrust_N_s2": k_value,
        "k_thrust_source": k_source,
        "thrust_map": amap.to_dict(),
    }
    QuadrotorParams.from_dict(section, source=f"{args.out} (about to be written)")
    metrics.update(
        {
            "epochs": result.epochs_run,
            "best_epoch": result.best_epoch + 1,
            "train_rmse_N": rmse(y_train, train.fz_N),
            "train_r2": r_squared(y_train, train.fz_N),
            "validation_rmse_N": rmse(y_val, val.fz_N),
            "validation_r2": r_squared(y_val, val.fz_N),
            "validation_pearson": pearson(y_val, val.fz_N),
            "polynomial_validation_rmse_N": {str(p.degree): p.test_rmse for p in polys},
            "best_polynomial_degree": best_poly.degree,
            "train_rmse_per_epoch_N": list(result.train_rmse),
            "check_rmse_per_epoch_N": list(result.check_rmse or ()),
            "band_us": list(amap.input_range[0]),
            "k_thrust_N_s2": k_value,
            "k_thrust_from_slope_N_s2": kc.k_N_s2 if kc else None,
            "k_thrust_from_level_N_s2": kc.k_from_level_N_s2 if kc else None,
            "mean_slope_N_per_us": kc.mean_slope_N_per_us if kc else None,
        }
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_json(args.out, {"quadrotor": section, "_identification": {"metrics": str(metrics_path)}})
    write_json(metrics_path, metrics)
    if args.plots:
        plots.thrust_training(
            args.plots / "fig4_training.png", result.train_rmse, result.check_rmse, result.best_epoch
        )
        plots.thrust_validation(
            args.plots / "fig5_validation.png",
            val.time_s,
            val.fz_N,
            y_val,
            val.sample_period_s,
            title=f"validation on {val_name}",
        )
        lo = min(train.pwm_sum_us.min(), val.pwm_sum_us.min())
        hi = max(train.pwm_sum_us.max(), val.pwm_sum_us.max())
        grid = np.linspace(lo, hi, 300)
        plots.thrust_curve(
            args.plots / "fig6_thrust_curve.png",
            np.concatenate([train.pwm_sum_us, val.pwm_sum_us]),
            np.concatenate([train.fz_N, val.fz_N]),
            [
                ("ANFIS", grid, predict(amap, grid)),
                (f"polynomial degree {best_poly.degree}", grid, best_poly(grid)),
            ],
            amap.input_range[0],
        )
    print(_summary(metrics, args, k_value))
    return EXIT_OK


def _correlation_table(corr: dict[str, float], gate: float, ds: Any) -> str:
    lag = f"{ds.lag_s * 1000:.0f} ms ({'estimated' if ds.lag_estimated else 'given'})"
    lines = [
        f"{ds.source}: {ds.n_samples} airborne samples, accelerometer lag {lag}",
        f"  {'candidate input':<22} {'Pearson r with F_z':>18}",
    ]
    for name, r in corr.items():
        mark = (
            "" if name != "pwm_sum_us" else ("  (gate passed)" if r >= gate else f"  (below gate {gate:.2f})")
        )
        lines.append(f"  {name:<22} {r:>18.3f}{mark}")
    return "\n".join(lines)


def _summary(m: dict[str, Any], args: argparse.Namespace, k_value: float) -> str:
    polys = ", ".join(f"deg {d}: {v:.3f}" for d, v in m["polynomial_validation_rmse_N"].items())
    rows = [
        ("samples train / validation", f"{m['n_train']} / {m['n_validation']}"),
        ("epochs (kept)", f"{m['epochs']} ({m['best_epoch']})"),
        ("train RMSE [N], R^2", f"{m['train_rmse_N']:.3f}, {m['train_r2']:.3f}"),
        ("validation RMSE [N], R^2", f"{m['validation_rmse_N']:.3f}, {m['validation_r2']:.3f}"),
        ("polynomial val. RMSE [N]", polys),
        ("trained band [us]", f"{m['band_us'][0]:.0f} .. {m['band_us'][1]:.0f}"),
        ("k_thrust [N s^2]", f"{k_value:.4g}"),
        ("parameters", str(args.out)),
        ("metrics", str(args.metrics or args.out.with_suffix(".metrics.json"))),
    ]
    width = max(len(r[0]) for r in rows)
    return "\n".join(f"  {a:<{width}}  {b}" for a, b in rows)
