"""Fly a ``uavfmu excite`` plan from a ground station by MAVLink RC override (ArduPilot or PX4).

    python docs/examples/excite_rc_override.py exc.rc_override.json --connect udp:127.0.0.1:14550 \\
        --autopilot ardupilot

Reads the RC inputs (RC_CHANNELS) once as the sticks' trim, then at each row's time sends RC_CHANNELS_OVERRIDE
with trim + offset on the planned channels, switching to the row's phase mode (``modes`` in the file: ArduPlane
MANUAL/FBWA, PX4 MANUAL/STABILIZED). ATTITUDE and VFR_HUD are watched: roll, pitch or airspeed outside the
file's ``limits`` (or Ctrl-C) switch to the recovery mode and release the override (0 = release, MAVLink
RC_CHANNELS_OVERRIDE). Try it in SITL first. ArduPilot: RC override needs ``SYSID_MYGCS`` to match the sender's
system id (255 here); PX4: MAVLink RC input must be enabled (``COM_RC_IN_MODE``) and the RC calibration must map
the channels (``RC_MAP_ROLL`` ...). The offsets assume stick PWM above trim = roll right, nose up, nose right;
check each channel's direction on the bench before flying.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable
from typing import Any

RELEASE = 0  #: RC_CHANNELS_OVERRIDE chan1..8: 0 releases the channel back to the RC radio


def outside_limits(msgs: dict[str, Any], limits: dict[str, float]) -> str | None:
    """Why the latest ATTITUDE / VFR_HUD are outside ``limits`` (None when inside)."""
    att, hud = msgs.get("ATTITUDE"), msgs.get("VFR_HUD")
    if att is not None:
        roll, pitch = math.degrees(att.roll), math.degrees(att.pitch)
        if abs(roll) > limits["roll_deg"]:
            return f"roll {roll:.0f} deg"
        if not limits["pitch_min_deg"] <= pitch <= limits["pitch_max_deg"]:
            return f"pitch {pitch:.0f} deg"
    if hud is not None and hud.airspeed < limits["min_airspeed_m_s"]:
        return f"airspeed {hud.airspeed:.1f} m/s"
    return None


def send(master: Any, values: dict[int, int]) -> None:
    """RC_CHANNELS_OVERRIDE of channels 1..8 (others released)."""
    ch = [int(values.get(k, RELEASE)) for k in range(1, 9)]
    master.mav.rc_channels_override_send(master.target_system, master.target_component, *ch)


def read_trim(master: Any, channels: list[int], timeout_s: float = 5.0) -> dict[int, int]:
    """The RC inputs of ``channels`` [us] from one RC_CHANNELS message."""
    msg = master.recv_match(type="RC_CHANNELS", blocking=True, timeout=timeout_s)
    if msg is None:
        raise RuntimeError("no RC_CHANNELS within the timeout: request the RC_CHANNELS stream first")
    return {c: int(getattr(msg, f"chan{c}_raw")) for c in channels}


def run(master: Any, plan: dict[str, Any], autopilot: str, clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep) -> str:
    """Send the rows of ``plan`` in time; returns "done" or "abort: <reason>"."""
    modes = plan["modes"][autopilot]
    channels = sorted(int(c) for c in plan["rows"][0]["offset_us"])
    trim = read_trim(master, channels)
    latest: dict[str, Any] = {}
    phase = None
    t0 = clock()
    try:
        for row in plan["rows"]:
            while clock() - t0 < row["t_s"]:
                msg = master.recv_match(type=["ATTITUDE", "VFR_HUD"], blocking=False)
                if msg is not None:
                    latest[msg.get_type()] = msg
                else:
                    sleep(0.002)
            if row["phase"] != phase:
                phase = row["phase"]
                master.set_mode(modes[phase])
            why = outside_limits(latest, plan["limits"]) if phase in ("excite", "hold") else None
            if why is not None:
                master.set_mode(modes["recover"])
                send(master, {})
                return f"abort: {why}"
            send(master, {c: trim[c] + round(row["offset_us"][str(c)]) for c in channels})
    except KeyboardInterrupt:
        master.set_mode(modes["recover"])
        send(master, {})
        return "abort: interrupted"
    master.set_mode(modes["recover"])
    send(master, {})
    return "done"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("plan", help="PREFIX.rc_override.json written by uavfmu excite")
    ap.add_argument("--connect", default="udp:127.0.0.1:14550", help="pymavlink connection string")
    ap.add_argument("--autopilot", choices=("ardupilot", "px4"), default="ardupilot")
    args = ap.parse_args()
    from pymavlink import mavutil

    with open(args.plan, encoding="utf-8") as f:
        plan = json.load(f)
    master = mavutil.mavlink_connection(args.connect, source_system=255)
    master.wait_heartbeat(timeout=10)
    print(run(master, plan, args.autopilot))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
