"""``uavfmu identify``: ``thrust`` (uavfmu.commands.identify_thrust), ``aero`` (uavfmu.commands.identify_aero) and
``quadrotor`` (uavfmu.commands.identify_quadrotor).

The sub-command modules are imported when ``identify`` is used, not by ``uavfmu`` itself.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``thrust``, ``aero`` and ``quadrotor`` sub-commands to ``parser``."""
    from uavfmu.commands import identify_aero, identify_quadrotor, identify_thrust

    sub = parser.add_subparsers(dest="identify_what", required=True)
    identify_thrust.add_arguments(
        sub.add_parser("thrust", help="thrust model of a quadrotor from one or more flight logs")
    )
    identify_aero.add_arguments(sub.add_parser("aero", help="fixed-wing aerodynamic derivatives (output error)"))
    identify_quadrotor.add_arguments(sub.add_parser(
        "quadrotor", help="quadrotor inertia, motor lag, yaw torque and drag (output error)"))


def run(args: argparse.Namespace) -> int:
    """Run the chosen ``identify`` sub-command; return the exit status."""
    if args.identify_what == "thrust":
        from uavfmu.commands import identify_thrust

        return identify_thrust.run(args)
    if args.identify_what == "quadrotor":
        from uavfmu.commands import identify_quadrotor

        return identify_quadrotor.run(args)
    from uavfmu.commands import identify_aero

    return int(identify_aero.run(args) or 0)
