"""``uavfmu identify aero``: fixed-wing stability and control derivatives from a flight log (output error).

``uavfmu identify aero LOG [LOG ...] [--init params.json] [--free auto|C_ell_p,...] --out identified.json
[--timeline FILE] [--segments t0:t1,...] [--validate-segments t0:t1,...] [--prior name=value:sd,...]
[--priors geometry|none] [--plots DIR] [--discrepancy [--discrepancy-mc N]]``

Inputs are the log's servo PWM through the HIL adapter's PWM mapping (``--mapping FILE.toml``, else the
log's ArduPilot ``SERVOn_*`` parameters; pull = nose up and right rudder = nose right map to the FMU's uavbook
signs). Several logs are pooled into one estimate (initial states and biases per segment). Segments follow
the manoeuvres: the blocks of a timeline file (``--timeline``, or ``LOG.timeline.json`` beside each log; the
middle of every three blocks of an axis is held out), else the spans where a control surface moves (every
third held out), else alternating airborne windows of ``--window`` seconds. Before the solve the
identifiability of the free set is printed (condition number, correlated pairs, input excitation, advice).
``--free auto`` (default) frees the primary derivatives, then the fixed coefficients that shift them by more
than their bound and that the data inform. Priors (a MAP term): a built-in estimate from the wing geometry
for C_ell_p, C_n_r, C_m_q, C_Y_beta, C_n_beta, C_m_alpha (``--priors none`` turns it off) and the user's
``--prior``/``--prior-file``; each estimate is reported as determined by the data or by the prior. Fixed
coefficients enter the bounds with their prior std (consider covariance; ``--no-consider`` turns it off), and so
does the noise of each segment's start state read from the log (``--no-start-noise`` turns it off). An
equation-error estimate (smoothed states, stepwise regression of the measured accelerations) starts the
output-error fit and is printed beside it. Per-segment initial rates and gyro/accelerometer biases are
estimated when they lower the Akaike criterion (``--nuisance auto``; ``--estimate-initial``/``--biases``
give them by hand), and a command -> surface delay is scanned from ``--min-delay`` (negative: the log shows the
command after the surfaces moved; 0 by default) up to ``--max-delay``. The console lists the log's measurement
chain with the values read from it; ``--sensor-filters`` models its gyro and accelerometer low-pass
(``INS_GYRO_FILTER``/``INS_ACCEL_FILTER``, PX4 ``IMU_GYRO_CUTOFF``/``IMU_ACCEL_CUTOFF``) on the model's rate
and specific-force outputs, ``--loop-ticks`` steps the fit on the autopilot's loop ticks with each loop's servo
command. ``--discrepancy`` (one log) then learns the model's discrepancy for ``validate --mc``'s prediction
bands where the truth is known and stores it in OUT beside ``uncertainty``: each segment, fit and held-out, is left
out in turn, identified on the others with the same options and replayed with that estimate; the quantiles are
learned on these out-of-sample replays and calibrated on ``--discrepancy-mc`` parameter draws of each
(``identification.validation.cross_fit``; one identification per segment). The work is
``identification.aero.identify``; this module parses and prints.

Exit status: 0 done, 2 bad input (unreadable log, a log damaged beyond ``--max-damage`` without ``--force``,
unknown parameter or output, bad segment or mapping),
3 the estimation failed (diverging start, no descent), 4 done but a rival (persistence, segment mean)
beats the model on a held-out output (its RMSE lower by more than 0.1 %; the rule of
``identification.common.metrics.SkillInterval``, as for ``identify thrust``), 5 estimates written but a late step
(scoring, plots, ``--discrepancy``) failed. A tie (no loss, but a skill interval that reaches zero) is printed as a
tie and is not a failure.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from identification.aero import HORIZON_RANGE_S
from identification.logs.flightlog import DEFAULT_MAX_DAMAGE
from uavfmu.commands.common import comma_list

if TYPE_CHECKING:
    from identification.aero.identify import AeroResult

EXIT_OK, EXIT_BAD_INPUT, EXIT_FAILED, EXIT_BASELINE_WINS, EXIT_LATE_FAILURE = 0, 2, 3, 4, 5


def _bounded(lo: float, hi: float, kind: type = float):  # type: ignore[no-untyped-def]
    def parse(text: str) -> float:
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not (math.isfinite(v) and lo <= v <= hi):
            raise argparse.ArgumentTypeError(f"{text} outside the allowed range {lo:g}..{hi:g}")
        return v
    return parse


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = __doc__.split("\n\n")[0]
    p.add_argument("log", type=Path, nargs="+", help="flight logs (.bin/.log DataFlash, .tlog, .ulg, .csv): pooled")
    p.add_argument("--free", default="auto", help="comma-separated parameters to estimate, or 'auto' (default)")
    p.add_argument("--timeline", type=Path, help="timeline file of the manoeuvres (one log; default: "
                   "LOG.timeline.json beside each log when present)")
    p.add_argument("--priors", choices=("geometry", "none"), default="geometry",
                   help="built-in prior from the wing geometry for six damping/stability derivatives (geometry)")
    p.add_argument("--prior", help="a-priori values name=value:sd,... (override the geometry ones)")
    p.add_argument("--prior-file", type=Path, help="JSON {name: {value, sd}} of a-priori values")
    p.add_argument("--no-consider", action="store_true",
                   help="leave the uncertainty of the fixed coefficients out of the bounds")
    p.add_argument("--no-start-noise", action="store_true",
                   help="count each segment's start state read from the log as exact (by default the noise of the "
                        "signals it is read from, estimated on the fit segments, enters the bounds)")
    p.add_argument("--no-equation-error", action="store_true",
                   help="skip the equation-error start and rival")
    p.add_argument("--out", type=Path, required=True, help="identified parameter file (JSON) to write")
    p.add_argument("--init", type=Path, help="start parameters (JSON; default: built-in Aerosonde)")
    p.add_argument("--outputs", help="comma-separated model outputs to fit (default: attitude, body rates, "
                   "accelerations incl. lateral, airspeed)")
    p.add_argument("--segments", help="fit segments t0:t1,... in seconds from log start (one log)")
    p.add_argument("--validate-segments", help="held-out segments t0:t1,... scored with the identified model")
    p.add_argument("--window", type=_bounded(0.2, 600.0), default=2.0, help="automatic segment length [s] (2)")
    p.add_argument("--rate", type=_bounded(1.0, 1000.0), default=50.0, help="resampling rate [Hz] (50)")
    p.add_argument("--mapping", type=Path, help="PWM mapping TOML (default: from the log's SERVOn_* parameters)")
    p.add_argument("--channel-map", type=Path, help="channel map for the log reader (TOML/JSON)")
    p.add_argument("--nuisance", choices=("auto", "none"), default="auto",
                   help="per-segment initial rates and output biases: auto (kept when they lower the AIC), none")
    p.add_argument("--estimate-initial", help="states whose initial value is estimated per segment (by hand)")
    p.add_argument("--initial-sd", metavar="STATE=SD,...",
                   help="estimated initial states whose logged start is a measurement of this std [state unit] (a "
                        "prior at the logged value), e.g. vel_body_y_m_s=0.07; default: estimated states are free")
    p.add_argument("--biases", help="outputs given a constant bias per segment (by hand)")
    p.add_argument("--max-delay", type=_bounded(0.0, 1.0), default=0.1,
                   help="longest command -> surface delay scanned [s] (0 turns the scan off; 0.1)")
    p.add_argument("--min-delay", type=_bounded(-1.0, 0.0), default=0.0,
                   help="most negative command -> surface delay scanned [s] (0; the shared SITL excitation log, "
                        "servo outputs logged at half the loop rate: -0.04)")
    p.add_argument("--sensor-filters", action="store_true",
                   help="pass the model's rates and specific forces through the log's gyro/accelerometer low-pass "
                        "(INS_GYRO_FILTER/INS_ACCEL_FILTER, PX4 IMU_GYRO_CUTOFF/IMU_ACCEL_CUTOFF)")
    p.add_argument("--loop-ticks", action="store_true",
                   help="step the fit on the autopilot's loop ticks (the gyro's time stamps, logs with "
                        "SCHED_LOOP_RATE) with each loop's servo command, an unlogged loop's as the mean of its "
                        "logged neighbours (default: hold each logged sample on a grid from the segment start)")
    p.add_argument("--estimate-unlogged", action="store_true",
                   help="with --loop-ticks: estimate the commands of the loops whose servo outputs were not logged "
                        "from the response (within their logged neighbours) and refit")
    p.add_argument("--bounds", help="bounds name=lo:hi,... on free parameters")
    p.add_argument("--sigma", help="fixed weighting B = diag(sigma^2): output=sigma,... for every fitted output "
                   "(default: maximum likelihood)")
    p.add_argument("--no-stability-constraints", action="store_true",
                   help="allow sign changes of C_ell_p, C_m_q, C_n_r, C_m_alpha, C_n_beta")
    p.add_argument("--max-iter", type=_bounded(1, 1000, int), default=40)
    p.add_argument("--horizon", type=_bounded(*HORIZON_RANGE_S), default=1.0,
                   help="continuation: first fitted span per segment [s], doubled up to the whole segment")
    p.add_argument("--restarts", metavar="S,S",
                   help="further continuation first spans [s] each cold fit is restarted with from the same start; "
                        "the lowest criterion is kept (at most 4; 'none' for a single schedule; default 0.5,2)")
    p.add_argument("--plots", type=Path, help="folder for PNG plots (fit, validation, residuals, parameters, "
                   "correlation)")
    p.add_argument("--metrics", type=Path, help="metrics JSON (default: OUT with suffix .metrics.json)")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--force", action="store_true",
                   help="use a log whose damaged or lost share exceeds --max-damage (the damage is still reported)")
    p.add_argument("--max-damage", type=_bounded(0.0, 1.0), default=DEFAULT_MAX_DAMAGE,
                   help="largest damaged or lost share of the log accepted, 0..1 (0.05)")
    p.add_argument("--discrepancy", action="store_true",
                   help="then learn the model's discrepancy for validate --mc's bands and store it in OUT: each "
                        "segment left out in turn, identified on the others and replayed with that estimate (one "
                        "identification per segment; one log)")
    p.add_argument("--discrepancy-mc", type=_bounded(0, 1e9, int), default=19, metavar="N",
                   help="with --discrepancy: parameter draws per segment to calibrate the band on (0 none, else "
                        "validate --mc's range; default 19)")


def _error(message: str) -> int:
    print(f"uavfmu identify aero: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _pairs(text: str | None, option: str) -> dict[str, str]:
    out = {}
    for item in comma_list(text):
        name, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"{option}: {item!r} is not name=value")
        out[name.strip()] = value.strip()
    return out


def _options(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    from identification.aero import model as aero
    from identification.aero.identify import AeroOptions

    bounds = {}
    for n, rng in _pairs(args.bounds, "--bounds").items():
        try:
            lo, hi = (float(v) for v in rng.split(":"))
        except ValueError:
            raise ValueError(f"--bounds: {n}={rng!r} is not name=lo:hi") from None
        bounds[n] = (lo, hi)
    sigma = None
    if args.sigma:
        try:
            sigma = {n: float(v) for n, v in _pairs(args.sigma, "--sigma").items()}
        except ValueError:
            raise ValueError(f"--sigma: {args.sigma!r} is not output=number,...") from None
    outputs = list(comma_list(args.outputs)) or list(aero.DEFAULT_OUTPUTS)
    if sigma is not None and (set(sigma) != set(outputs) or not all(v > 0 and math.isfinite(v)
                                                                     for v in sigma.values())):
        raise ValueError(f"--sigma needs a positive value for each fitted output ({', '.join(outputs)}), "
                         f"got {args.sigma!r}")
    try:
        initial_sd = {n: float(v) for n, v in _pairs(args.initial_sd, "--initial-sd").items()}
    except ValueError:
        raise ValueError(f"--initial-sd: {args.initial_sd!r} is not state=number,...") from None
    restarts: dict[str, tuple[float, ...]] = {}
    if args.restarts is not None:
        try:
            restarts["restart_horizons_s"] = () if args.restarts.strip() == "none" else tuple(
                float(x) for x in comma_list(args.restarts))
        except ValueError:
            raise ValueError(f"--restarts: {args.restarts!r} is not seconds,... ('none' for one schedule)") from None
    given = bool(args.estimate_initial or args.biases)
    free = "auto" if args.free.strip() == "auto" else list(comma_list(args.free))
    if len(args.log) > 1 and args.discrepancy:
        raise ValueError(f"--discrepancy leaves the segments of one log out in turn; got {len(args.log)} logs")
    if args.discrepancy and args.discrepancy_mc:
        from identification.validation.mc_bands import MAX_DRAWS, MIN_DRAWS

        if not MIN_DRAWS <= args.discrepancy_mc <= MAX_DRAWS:
            raise ValueError(f"--discrepancy-mc {args.discrepancy_mc}: 0 (none) or {MIN_DRAWS}..{MAX_DRAWS} draws "
                             f"(a 5-95 % band needs {MIN_DRAWS})")
    if len(args.log) > 1 and (args.segments or args.validate_segments or args.timeline):
        raise ValueError("--segments, --validate-segments and --timeline take one log; with several logs "
                         "put LOG.timeline.json beside each log")
    from fmu_models.fixed_wing.params import FixedWingParams
    from identification.aero.priors import load_priors, parse_priors

    known = set(FixedWingParams().to_dict())
    priors = load_priors(args.prior_file, known) if args.prior_file else {}
    priors.update(parse_priors(args.prior, known) if args.prior else {})
    return AeroOptions(
        free=free, outputs=tuple(outputs),
        segments=aero.parse_segments(args.segments) if args.segments else None,
        validate_segments=aero.parse_segments(args.validate_segments, "--validate-segments")
        if args.validate_segments else None,
        window_s=args.window, rate_hz=args.rate, nuisance="given" if given else args.nuisance,
        estimate_initial=list(comma_list(args.estimate_initial)), biases=list(comma_list(args.biases)), bounds=bounds,
        initial_sd=initial_sd, sigma=sigma,
        stability_constraints=not args.no_stability_constraints, max_iter=args.max_iter, horizon_s=args.horizon,
        max_delay_s=args.max_delay, min_delay_s=args.min_delay, sensor_filters=None if args.sensor_filters else {},
        progress=not args.quiet, force=args.force, max_damage=args.max_damage,
        priors=args.priors, prior_values=priors, consider=not args.no_consider, start_noise=not args.no_start_noise,
        timeline=args.timeline,
        equation_error=not args.no_equation_error, loop_ticks=args.loop_ticks, estimate_unlogged=args.estimate_unlogged,
        **restarts)


def run(args: argparse.Namespace) -> int:
    """Read, estimate, write, print; see the module docstring."""
    from fmu_models.common.errors import ParameterError
    from fmu_models.fixed_wing.params import FixedWingParams
    from fmu_models.fmi.fmus import load_vehicle_params
    from fmu_models.signals.pwm_mapping import PwmMapping
    from identification.aero.identify import AeroInputError, AeroSource, identify_aero, write_results
    from identification.estimation.oem import EstimationError
    from identification.logs.readers import read_log

    if not args.quiet:
        logging.basicConfig(level=logging.ERROR, format="%(levelname)s %(name)s: %(message)s")
    try:
        opt = _options(args)
        init = load_vehicle_params(args.init, "fixed_wing") if args.init else FixedWingParams()
        sources = []
        for path in args.log:
            log = read_log(path, channel_map=args.channel_map)
            mapping = PwmMapping.load(args.mapping) if args.mapping else PwmMapping.from_ardupilot(log.params)
            sources.append(AeroSource(log, mapping, opt.timeline, opt.segments, opt.validate_segments))
        result = identify_aero(sources, None, init, opt)
    except AeroInputError as err:
        return _error(str(err))
    except EstimationError as err:
        print(f"estimation failed, nothing written: {err}")
        print(f"uavfmu identify aero: estimation failed: {err}", file=sys.stderr)
        return EXIT_FAILED
    except (OSError, ValueError, KeyError, ParameterError) as err:  # LogError, MappingError, ConfigError, ...
        return _error(str(err).strip("'\""))
    metrics = args.metrics or args.out.with_suffix(".metrics.json")
    write_results(result, args.out, metrics, ", ".join(map(str, args.log)), args.rate, args.plots)
    print(result.summary())
    print(f"parameters: {args.out}\nmetrics: {metrics}")
    if args.discrepancy and _discrepancy(args, result, opt, init) != EXIT_OK:
        return EXIT_LATE_FAILURE
    return exit_status(result)


def _discrepancy(args: argparse.Namespace, result: AeroResult, opt, init) -> int:  # type: ignore[no-untyped-def]
    """``--discrepancy``: the cross-fitted discrepancy stored in ``--out``; the estimate is already written, so a
    failure here is a late one."""
    import tempfile

    from fmu_models.fmi.host import FmuRunError
    from identification.validation.cross_fit import cross_fitted_discrepancy

    segments = sorted([*result.fit_segments, *result.validation_segments], key=lambda g: g.t0_s)
    print(f"discrepancy: each of the {len(segments)} segments left out in turn ...")
    try:
        with tempfile.TemporaryDirectory() as tmp:
            out = cross_fitted_discrepancy(args.log[0], segments, opt, init, Path(tmp), params_out=args.out,
                                           draws=args.discrepancy_mc, mapping_file=args.mapping,
                                           channel_map=args.channel_map,
                                           progress=None if args.quiet else lambda m: print(f"  {m}"))
    except (FmuRunError, OSError, ValueError, KeyError) as err:  # ValidationInputError, ConfigError are ValueErrors
        print(f"uavfmu identify aero: --discrepancy failed (the estimate is written): {err}", file=sys.stderr)
        return EXIT_LATE_FAILURE
    print("\n".join(out.lines()))
    return EXIT_OK


def exit_status(result: AeroResult) -> int:
    """5 after a late failure, 4 when a rival beats the model on a held-out output (a tie is not a failure),
    else 0."""
    if result.failures:
        return EXIT_LATE_FAILURE
    return EXIT_BASELINE_WINS if result.losing_outputs else EXIT_OK
