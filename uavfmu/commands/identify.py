"""``uavfmu identify``: ``thrust`` (uavfmu.commands.identify_thrust) and ``aero`` (fixed wing).

``aero`` runs ``uavfmu.commands.identify_aero`` when it exists, else hands its arguments unparsed to
``identification.aero_cli``. Sub-command modules are imported only when needed.
"""

from __future__ import annotations

import argparse
import importlib
from types import ModuleType


def _aero_module() -> ModuleType | None:
    try:
        return importlib.import_module("uavfmu.commands.identify_aero")
    except ModuleNotFoundError as err:
        if err.name != "uavfmu.commands.identify_aero":
            raise
        return None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``thrust`` and ``aero`` sub-commands to ``parser``."""
    from identification.cli import _SubParser  # passthrough parser for the fallback of ``aero``

    sub = parser.add_subparsers(dest="identify_what", required=True, parser_class=_SubParser)
    th = sub.add_parser("thrust", help="thrust model of a quadrotor from one or more flight logs")
    from uavfmu.commands import identify_thrust

    identify_thrust.add_arguments(th)
    aero = _aero_module()
    if aero is not None:
        aero.add_arguments(sub.add_parser("aero", help="fixed-wing aerodynamic derivatives (output error)"))
    else:
        sub.add_parser("aero", passthrough=True, help="fixed-wing aerodynamic derivatives (identification.aero_cli)")


def run(args: argparse.Namespace) -> int:
    """Run the chosen ``identify`` sub-command; return the exit status."""
    if args.identify_what == "thrust":
        from uavfmu.commands import identify_thrust

        return identify_thrust.run(args)
    aero = _aero_module()
    if aero is not None:
        return int(aero.run(args) or 0)
    from identification.cli import _run_aero

    return _run_aero(getattr(args, "rest_argv", []))
