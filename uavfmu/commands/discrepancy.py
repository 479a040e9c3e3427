"""``uavfmu discrepancy FMU LOG [LOG ...] --params FILE``: learn how far the FMU's replays are from the logs.

Replays each log through the FMU as ``uavfmu validate`` does (same windows, rate, output map, PWM mapping and
battery feed), pools the residuals logged - FMU per signal and horizon, and writes their empirical quantiles into
the JSON parameter file ``FILE`` under ``discrepancy``, beside ``uncertainty``
(``identification.validation.discrepancy``). With ``--mc N`` (default 19 when FILE holds an ``uncertainty``) each
log is also replayed N times with the parameters drawn, and the combined band is calibrated on them
(``band_factor``; with two logs or more, ``parameter_weight`` 0 where the draws' spread widened the band of a
log left out more than it helped). ``uavfmu validate --mc`` then convolves it with the parameter draws. Give
flights the FMU's parameters were not fitted on where you have them (the bands are then honest on new flights).
The work is done by ``identification.validation.workflow.learn_discrepancy``; this module parses and prints.

Exit status: 0 written, 2 bad input.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

EXIT_OK, EXIT_BAD_INPUT = 0, 2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__.split("\n\n")[0]
    parser.add_argument("fmu", type=Path, help="the FMU (built from --params, or with the same parameters)")
    parser.add_argument("logs", type=Path, nargs="+", help="flight logs to learn from")
    parser.add_argument("--params", type=Path, required=True, help="JSON parameter file to store the discrepancy in")
    parser.add_argument("--map", type=Path, help="output map TOML (as validate)")
    parser.add_argument("--mapping", type=Path, help="PWM mapping TOML for fixed-wing surfaces and throttle")
    parser.add_argument("--channel-map", type=Path, help="TOML/JSON [channels] for the logs' outputs")
    parser.add_argument("--window-s", type=float, help="replay windows [s] (default 2; use validate's)")
    parser.add_argument("--rate-hz", type=float, help="replay sample rate [Hz] (default 50)")
    parser.add_argument("--include-ground", action="store_true", default=None, help="also ground windows")
    parser.add_argument("--start-velocity", choices=("force", "logged"), default=None,
                        help="fixed wing: window start velocity from the specific force (default) or the GPS (as "
                             "validate)")
    parser.add_argument("--mc", type=int, default=None, metavar="N",
                        help="Monte Carlo draws of the parameters per log to calibrate the combined band on (default "
                        "19 when --params holds an 'uncertainty', 0: none; then validate --mc counts the parameter "
                        "spread on top of residuals that already carry it)")


def run(args: argparse.Namespace) -> int:
    from fmu_models.common.errors import ParameterError
    from fmu_models.config import ConfigError
    from fmu_models.fmi.host import FmuRunError
    from identification.validation.mc_bands import MAX_DRAWS, MIN_DRAWS
    from identification.validation.replay import check_options
    from identification.validation.workflow import ValidationJob, learn_discrepancy

    try:
        values = {"window_s": args.window_s, "rate_hz": args.rate_hz, "include_ground": args.include_ground,
                  "start_velocity": args.start_velocity}
        opts = check_options(**{k: v for k, v in values.items() if v is not None})
        job = ValidationJob(args.fmu, args.logs[0], opts, args.map, args.mapping, args.channel_map,
                            params_file=args.params)
        unc = _uncertainty(args.params)
        draws = (MIN_DRAWS if unc is not None else 0) if args.mc is None else args.mc
        if draws and unc is None:
            raise ValueError(f"--mc {draws}: {args.params} has no 'uncertainty' to draw the parameters from")
        if draws and not MIN_DRAWS <= draws <= MAX_DRAWS:
            raise ValueError(f"--mc = {draws}: allowed 0 or {MIN_DRAWS}..{MAX_DRAWS}")
        result = learn_discrepancy(job, args.logs, args.params, unc, draws)
    except (ValueError, ConfigError, ParameterError, FmuRunError, OSError, KeyError) as err:
        print(f"uavfmu discrepancy: error: {str(err).strip(chr(39) + chr(34))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print("\n".join(result.lines()))
    return EXIT_OK


def _uncertainty(params: Path) -> Any:
    """The ``uncertainty`` block of ``params`` when it has one (None otherwise; a malformed one raises)."""
    from fmu_models.common.params import read_json, uncertainty_of

    data = read_json(params) if params.exists() else {}
    return uncertainty_of(data, str(params)) if "uncertainty" in data else None
