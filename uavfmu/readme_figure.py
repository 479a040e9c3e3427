"""The README's figure: a validation overlay from the demo's output, ``python -m uavfmu.readme_figure``.

Replays the demo's held-out fixed-wing flight through the FMU rebuilt with the identified roll derivatives
(the same library call as ``uavfmu validate``) and draws, for two signals, the log, the FMU and the
persistence baseline over a stretch of replay windows, with each signal's verdict and the 90 % interval of its
skill against persistence in the legend. Run ``make demo`` first.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

SIGNALS = ("roll_rad", "rate_body_x_rad_s")


def draw(demo_dir: Path, out: Path, t_range_s: tuple[float, float] = (2.0, 22.0)) -> Path:
    """Write the overlay PNG to ``out`` from ``demo_dir`` (``dist/demo`` after ``make demo``)."""
    from identification.common.plots import figure, save
    from identification.validation.replay import options
    from identification.validation.workflow import ValidationJob, validate

    fmu = demo_dir / "identified_fmus" / "fixed_wing.fmu"
    log = demo_dir / "logs" / "fixed_wing_flight_held_out.bin"
    missing = [str(p) for p in (fmu, log) if not p.is_file()]
    if missing:
        raise SystemExit(f"readme_figure: {', '.join(missing)} not found: run `make demo` first")
    res = validate(ValidationJob(fmu, log, options(window_s=2.0, rate_hz=50.0))).replay
    assert res is not None
    keep = (res.t_s >= t_range_s[0]) & (res.t_s <= t_range_s[1])
    fig, axes = figure(len(SIGNALS), 1, figsize=(8.0, 4.2), sharex=True)
    for ax, name in zip(axes, SIGNALS, strict=True):
        s = res.scores[name]
        t = res.t_s[keep]
        ax.plot(t, np.degrees(res.measured[name][keep]), color="0.2", lw=1.2, label="log (held-out flight)")
        ax.plot(t, np.degrees(res.model[name][keep]), color="tab:blue", lw=1.0, label="FMU, restarted every 2 s")
        ax.plot(t, np.degrees(res.persistence[name][keep]), color="tab:orange", lw=0.9, ls="--",
                label="persistence baseline")
        band = s.interval
        ax.set_ylabel(name.replace("_rad_s", " [deg/s]").replace("_rad", " [deg]"), fontsize=8)
        ax.set_title(f"{name}: {s.verdict}, skill vs persistence {s.skill_persistence:+.2f} "
                     f"(90 % interval {band.lo:+.2f}..{band.hi:+.2f})" if band else name, fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0].legend(fontsize=7, loc="upper left", ncol=3)
    axes[-1].set_xlabel("time [s]", fontsize=8)
    return save(fig, out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m uavfmu.readme_figure", description=__doc__.splitlines()[0])
    parser.add_argument("--demo", type=Path, default=Path("dist/demo"), help="the demo's work folder")
    parser.add_argument("--out", type=Path, default=Path("docs/img/validation_overlay.png"))
    args = parser.parse_args(argv)
    print(f"wrote {draw(args.demo, args.out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
