"""``uavfmu identify aero``: fixed-wing stability and control derivatives from a flight log (output error).

``uavfmu identify aero LOG [--init params.json] --free C_ell_p,C_ell_delta_a,... --out identified.json
[--segments t0:t1,...] [--validate-segments t0:t1,...] [--plots DIR]``

Inputs are the log's servo PWM through the HIL adapter's PWM mapping (``--mapping FILE.toml``, else the
log's ArduPilot ``SERVOn_*`` parameters). Without ``--segments`` the airborne part of the log is cut into
windows of ``--window`` seconds; every other window is fitted and the rest held out for validation. The
output file holds the whole fixed-wing parameter set (``--init`` or the built-in Aerosonde, with the
estimates in place) and feeds ``build_fmus.py --params``; a metrics JSON beside it holds the estimates,
their Cramér-Rao bounds, correlations, convergence history and the fit metrics per output and segment set.

Exit status: 0 done, 2 bad input (unreadable log, unknown parameter or output, bad segment or mapping),
3 the estimation failed (diverging start, no descent).
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Any

import numpy as np

EXIT_OK = 0
EXIT_BAD_INPUT = 2
EXIT_FAILED = 3

#: sign constraints that keep the identified model stable (paper 001 rejects diverging models): damping
#: derivatives negative, static stability in pitch and yaw, roll damping negative
STABILITY_SIGNS = {"C_ell_p": -1, "C_m_q": -1, "C_n_r": -1, "C_m_alpha": -1, "C_n_beta": +1}


def _names(text: str | None) -> list[str]:
    return [s.strip() for s in (text or "").split(",") if s.strip()]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = __doc__.split("\n\n")[0]
    p.add_argument("log", type=Path, help="flight log (.bin/.log DataFlash, .tlog, .ulg, .csv)")
    p.add_argument("--free", required=True, help="comma-separated parameters to estimate, e.g. C_ell_p,C_ell_delta_a")
    p.add_argument("--out", type=Path, required=True, help="identified parameter file (JSON) to write")
    p.add_argument("--init", type=Path, help="start parameters (JSON; default: built-in Aerosonde)")
    p.add_argument("--outputs", help="comma-separated model outputs to fit (default: attitude, body rates, "
                   "accelerations, airspeed)")
    p.add_argument("--segments", help="fit segments t0:t1,... in seconds from log start")
    p.add_argument("--validate-segments", help="held-out segments t0:t1,... scored with the identified model")
    p.add_argument("--window", type=float, default=2.0,
                   help="automatic segment length [s] (default 2: short records keep slow-mode drift small)")
    p.add_argument("--rate", type=float, default=50.0, help="resampling rate [Hz] (default 50)")
    p.add_argument("--mapping", type=Path, help="PWM mapping TOML (default: from the log's SERVOn_* parameters)")
    p.add_argument("--channel-map", type=Path, help="channel map for the log reader (TOML/JSON)")
    p.add_argument("--estimate-initial", help="states whose initial value is estimated per segment")
    p.add_argument("--biases", help="outputs given a constant bias per segment")
    p.add_argument("--bounds", help="bounds name=lo:hi,... on free parameters")
    p.add_argument("--sigma", help="fixed weighting B = diag(sigma^2): output=sigma,... for every fitted output "
                   "(default: maximum likelihood, residual covariance re-estimated each iteration)")
    p.add_argument("--no-stability-constraints", action="store_true",
                   help=f"allow sign changes of {', '.join(STABILITY_SIGNS)}")
    p.add_argument("--max-iter", type=int, default=40)
    p.add_argument("--horizon", type=float, default=1.0,
                   help="continuation: first fitted span per segment [s], doubled up to the whole segment")
    p.add_argument("--plots", type=Path, help="folder for PNG plots (fit, validation, residuals, parameters)")
    p.add_argument("--metrics", type=Path, help="metrics JSON (default: OUT with suffix .metrics.json)")
    p.add_argument("--quiet", action="store_true", help="no progress display")


def _error(message: str) -> int:
    print(f"uavfmu identify aero: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _bounds(text: str | None) -> dict[str, tuple[float, float]]:
    out = {}
    for item in _names(text):
        try:
            name, rng = item.split("=")
            lo, hi = (float(v) for v in rng.split(":"))
        except ValueError:
            raise ValueError(f"--bounds: {item!r} is not name=lo:hi") from None
        out[name.strip()] = (lo, hi)
    return out


def _weight(text: str | None, outputs: list[str]) -> np.ndarray | None:
    """``--sigma`` into the weighting matrix W = B^-1 (eq. 9 of paper 001)."""
    if not text:
        return None
    sig: dict[str, float] = {}
    for item in _names(text):
        try:
            name, value = item.split("=")
            sig[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--sigma: {item!r} is not output=value") from None
    if set(sig) != set(outputs) or not all(v > 0 for v in sig.values()):
        raise ValueError(f"--sigma needs a positive value for each fitted output ({', '.join(outputs)}), got {text!r}")
    return np.diag([1.0 / sig[n] ** 2 for n in outputs])


def run(args: argparse.Namespace) -> int:
    """Read, cut, estimate, validate, write; see the module docstring."""
    from fmu_models.common.errors import ParameterError
    from fmu_models.fixed_wing.model import FixedWingModel
    from fmu_models.fixed_wing.params import FixedWingParams
    from fmu_models.signals.pwm_mapping import PwmMapping
    from identification import aero
    from identification.jsonio import write_json
    from identification.oem import EstimationError, OutputErrorEstimator
    from identification.readers import read_log

    if not args.quiet:
        logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        init = FixedWingParams.load(args.init) if args.init else FixedWingParams()
        log = read_log(args.log, channel_map=args.channel_map)
        mapping = PwmMapping.load(args.mapping) if args.mapping else PwmMapping.from_ardupilot(log.params)
        model = FixedWingModel(init)
        p = np.array(model.params.starts(), dtype=float)
        free = _names(args.free)
        outputs = _names(args.outputs) or list(aero.DEFAULT_OUTPUTS)
        if args.segments:
            fit_segs = aero.parse_segments(args.segments)
            val_segs = aero.parse_segments(args.validate_segments, "--validate-segments") \
                if args.validate_segments else []
        else:
            auto = aero.airborne_segments(log, args.window)
            if len(auto) < 2:
                return _error(f"{args.log}: fewer than two airborne windows of {args.window:g} s; give --segments")
            fit_segs, val_segs = auto[0::2], auto[1::2]
            if args.validate_segments:
                val_segs = aero.parse_segments(args.validate_segments, "--validate-segments")
        bounds = _bounds(args.bounds)
        constraints = []
        if not args.no_stability_constraints:
            for name, sign in STABILITY_SIGNS.items():
                if name in free:
                    constraints.append(lambda th, n=name, s=sign: s * th[n] > 0)
        oe = OutputErrorEstimator(model, p, free, outputs, bounds=bounds, constraints=constraints,
                         estimate_states=_names(args.estimate_initial), estimate_biases=_names(args.biases))
        weight = _weight(args.sigma, outputs)
        fit = aero.manoeuvres(model, p, log, mapping, fit_segs, outputs, args.rate)
        val = aero.manoeuvres(model, p, log, mapping, val_segs, outputs, args.rate)
    except (OSError, ValueError, KeyError, ParameterError) as err:  # LogError, MappingError, ... are ValueErrors
        return _error(str(err).strip("'\""))

    start = p[oe.i_free].copy()
    try:
        est = oe.estimate(fit, weight=weight, max_iter=args.max_iter, progress=not args.quiet, horizon_s=args.horizon)
    except EstimationError as err:
        print(f"uavfmu identify aero: estimation failed: {err}", file=sys.stderr)
        return EXIT_FAILED

    theta = est.values[:len(free)]
    fit_y, fit_m, fit_t = _replay(oe, est.values, fit, fit_segs, args.rate)
    scores = {"fit": aero.score(fit_y, fit_m, outputs)}
    if val:
        val_y, val_m, val_t = _replay(oe, theta, val, val_segs, args.rate)
        scores["validation"] = aero.score(val_y, val_m, outputs)

    identified = init.to_dict()
    identified.update({n: float(v) for n, v in zip(free, theta, strict=True)})
    report = {
        "log": str(args.log), "free": free, "outputs": outputs, "rate_hz": args.rate,
        "fit_segments": [str(s) for s in fit_segs], "validation_segments": [str(s) for s in val_segs],
        "start": {n: float(v) for n, v in zip(free, start, strict=True)},
        "estimate": est.as_dict(),
        "metrics": {k: {n: m.as_dict() for n, m in v.items()} for k, v in scores.items()},
    }
    write_json(args.out, {"fixed_wing": identified, "_identification": {
        "method": "output error (identification.oem)", "log": str(args.log), "free": free,
        "crb_std": {n: float(s) for n, s in zip(free, est.crb_std, strict=True)}}})
    metrics_path = args.metrics or args.out.with_suffix(".metrics.json")
    write_json(metrics_path, report)
    if args.plots:
        from identification import plots

        dt = 1.0 / args.rate
        plots.aero_overlay(args.plots / "fit.png", "fit segments", fit_t, fit_y, fit_m, outputs, dt,
                           {n: m.theil_u for n, m in scores["fit"].items()})
        plots.aero_residuals(args.plots / "residuals.png", fit_t, fit_y - fit_m, outputs, dt)
        if val:
            plots.aero_overlay(args.plots / "validation.png", "held-out segments", val_t, val_y, val_m, outputs,
                               dt, {n: m.theil_u for n, m in scores["validation"].items()})
        plots.aero_parameters(args.plots / "parameters.png", free, start, theta, est.crb_std[:len(free)],
                              oe.lower, oe.upper)
    print(_summary(est, scores, args.out, metrics_path))
    return EXIT_OK


def _replay(oe: Any, theta: np.ndarray, data: list[Any], segs: list[Any], rate: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Measured and simulated outputs over all segments, with their log times."""
    ys, ms, ts = [], [], []
    for j, (m, s) in enumerate(zip(data, segs, strict=True)):
        y, _, _ = oe.simulate(theta, m, j, sensitivities=False)
        ys.append(m.y)
        ms.append(y)
        ts.append(s.t0_s + np.arange(1, len(y) + 1) / rate)
    return np.vstack(ys), np.vstack(ms), np.concatenate(ts)


def _summary(est: Any, scores: dict[str, Any], out: Path, metrics: Path) -> str:
    lines = [est.table(), ""]
    if not est.converged:
        lines.append("NOT CONVERGED within --max-iter; the estimates are the last accepted iterate")
    lines.append(f"{'output':<22} " + " ".join(f"{'Theil U ' + k:>20}" for k in scores))
    for name in next(iter(scores.values())):
        lines.append(f"{name:<22} " + " ".join(f"{scores[k][name].theil_u:>20.3f}" for k in scores))
    lines += [*(f"warning: {w}" for w in est.warnings), f"parameters: {out}", f"metrics: {metrics}"]
    return "\n".join(lines)
