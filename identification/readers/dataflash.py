"""ArduPilot DataFlash logs (binary ``.bin`` and text ``.log``) through pymavlink's DFReader.

Handles the old ``TimeMS`` and the newer ``TimeUS`` time stamps, maps vendor messages to the canonical
signals of docs/interfaces.md, keeps every raw field as ``MSG.Field`` and the PARM parameters.
"""

from __future__ import annotations

import math
import struct
from collections import defaultdict
from pathlib import Path

import numpy as np
from pymavlink import DFReader

from identification.flightlog import FlightLog, LogError, Signal

DEG = math.pi / 180.0
#: ArduPilot SERVOn_FUNCTION values
MOTOR_FUNCTIONS = {33: 1, 34: 2, 35: 3, 36: 4, 37: 5, 38: 6, 39: 7, 40: 8}
SURFACE_FUNCTIONS = {4: "aileron", 19: "elevator", 70: "throttle", 21: "rudder"}
#: ArduPilot EV ids: 10 armed, 11 disarmed
EV_ARMED, EV_DISARMED = 10, 11

# canonical name <- (message, field, scale to SI, unit)
CANONICAL: list[tuple[str, str, str, float, str]] = [
    ("accel_body_x_m_s2", "IMU", "AccX", 1.0, "m/s2"),
    ("accel_body_y_m_s2", "IMU", "AccY", 1.0, "m/s2"),
    ("accel_body_z_m_s2", "IMU", "AccZ", 1.0, "m/s2"),
    ("gyro_body_x_rad_s", "IMU", "GyrX", 1.0, "rad/s"),
    ("gyro_body_y_rad_s", "IMU", "GyrY", 1.0, "rad/s"),
    ("gyro_body_z_rad_s", "IMU", "GyrZ", 1.0, "rad/s"),
    ("roll_rad", "ATT", "Roll", DEG, "rad"),
    ("pitch_rad", "ATT", "Pitch", DEG, "rad"),
    ("yaw_rad", "ATT", "Yaw", DEG, "rad"),
    ("lat_deg", "GPS", "Lat", 1.0, "deg"),
    ("lon_deg", "GPS", "Lng", 1.0, "deg"),
    ("height_m", "GPS", "Alt", 1.0, "m"),
    ("altitude_m", "CTUN", "Alt", 1.0, "m"),
    ("airspeed_m_s", "ARSP", "Airspeed", 1.0, "m/s"),
    ("battery_voltage_V", "BAT", "Volt", 1.0, "V"),
]


def _time_s(d: dict) -> float | None:
    """Boot time [s]. Old GPS messages carry GPS time of week in ``TimeMS`` and boot time in ``T``."""
    if d.get("mavpackettype") == "GPS" and "T" in d and "Week" in d:
        return d["T"] * 1e-3
    if "TimeUS" in d:
        return d["TimeUS"] * 1e-6
    if "TimeMS" in d:
        return d["TimeMS"] * 1e-3
    return None


def read_dataflash(path: Path, channel_map: dict[str, int] | None = None) -> FlightLog:
    """Read ``path``; a damaged tail yields the intact part and a warning saying how much was dropped."""
    try:
        reader = DFReader.DFReader_binary(str(path)) if path.suffix.lower() == ".bin" else \
            DFReader.DFReader_text(str(path))
    except (OSError, ValueError, IndexError, KeyError) as err:
        raise LogError(f"{path}: not a readable DataFlash log ({err})") from err
    raw: dict[str, list[tuple[float, dict]]] = defaultdict(list)
    params: dict[str, float] = {}
    last_offset = 0
    n_msgs = 0
    while True:
        try:
            msg = reader.recv_msg()
        except (struct.error, ValueError, IndexError, KeyError) as err:
            warn = f"stopped at a damaged message ({err})"
            raw.setdefault("_warnings", []).append((0.0, {"text": warn}))
            break
        if msg is None:
            break
        n_msgs += 1
        last_offset = getattr(reader, "offset", last_offset)
        mtype = msg.get_type()
        if mtype == "PARM":
            params[str(msg.Name)] = float(msg.Value)
            continue
        if mtype in ("FMT", "FMTU", "UNIT", "MULT", "MSG"):
            continue
        d = msg.to_dict()
        t = _time_s(d)
        if t is None:
            continue
        raw[mtype].append((t, {k: v for k, v in d.items() if isinstance(v, int | float)}))
    warnings = [w[1]["text"] for w in raw.pop("_warnings", [])]
    size = path.stat().st_size
    data_len = getattr(reader, "data_len", size)
    if isinstance(reader, DFReader.DFReader_binary) and data_len - last_offset > 0:
        warnings.append(f"{path}: {data_len - last_offset} of {data_len} bytes at the end could not be parsed "
                        "and were dropped (truncated or corrupt tail)")
    if n_msgs == 0 or not raw:
        raise LogError(f"{path}: no timestamped messages found (empty or not a DataFlash log)")
    t0 = min(v[0][0] for v in raw.values() if v)
    signals: dict[str, Signal] = {}
    for mtype, rows in raw.items():
        t = np.array([r[0] for r in rows]) - t0
        order = np.argsort(t, kind="stable")
        for fld in rows[0][1]:
            vals = np.array([r[1].get(fld, np.nan) for r in rows], dtype=float)[order]
            signals[f"{mtype}.{fld}"] = Signal(f"{mtype}.{fld}", t[order], vals, "", f"raw {mtype}.{fld}")
    for name, mtype, fld, scale, unit in CANONICAL:
        key = f"{mtype}.{fld}"
        if key in signals and name not in signals:
            s = signals[key]
            signals[name] = Signal(name, s.t_s, s.values * scale, unit, f"from {key}")
    if all(f"GPS.{f}" in signals for f in ("Spd", "GCrs", "VZ")):  # ground speed, course [deg], VZ down (NED)
        spd, crs, vz = (signals[f"GPS.{f}"] for f in ("Spd", "GCrs", "VZ"))
        course = crs.values * DEG
        for name, vals in (("vel_north_m_s", spd.values * np.cos(course)),
                           ("vel_east_m_s", spd.values * np.sin(course)), ("vel_down_m_s", vz.values)):
            signals[name] = Signal(name, spd.t_s, vals, "m/s", "from GPS.Spd/GCrs/VZ")
    if "altitude_m" not in signals and "BARO.Alt" in signals:
        s = signals["BARO.Alt"]
        signals["altitude_m"] = Signal("altitude_m", s.t_s, s.values, "m", "from BARO.Alt")
    if "CTUN.CRt" in signals:
        s = signals["CTUN.CRt"]
        scale = 0.01 if np.nanmax(np.abs(s.values)) > 50 else 1.0  # old logs: cm/s
        signals["climb_rate_m_s"] = Signal("climb_rate_m_s", s.t_s, s.values * scale, "m/s", "from CTUN.CRt")
    # servo outputs: RCOU C1.. (new) or Ch1.. (old)
    for n in range(1, 33):
        for key in (f"RCOU.C{n}", f"RCOU.Ch{n}"):
            if key in signals:
                s = signals[key]
                signals[f"servo_{n}_pwm_us"] = Signal(f"servo_{n}_pwm_us", s.t_s, s.values, "us", f"from {key}")
                break
    vehicle = None
    functions = {n: int(params[f"SERVO{n}_FUNCTION"]) for n in range(1, 33) if f"SERVO{n}_FUNCTION" in params}
    mapping: dict[str, int] = {}
    if functions:
        for n, fn in functions.items():
            if fn in MOTOR_FUNCTIONS:
                mapping[f"motor_{MOTOR_FUNCTIONS[fn]}_pwm_us"] = n
            elif fn in SURFACE_FUNCTIONS:
                mapping[f"{SURFACE_FUNCTIONS[fn]}_pwm_us"] = n
    elif "FRAME" in params or any(k.startswith("MOT_") for k in params):
        mapping = {f"motor_{k}_pwm_us": k for k in range(1, 5)}  # old ArduCopter: motors on outputs 1-4
    mapping.update(channel_map or {})
    for name, n in mapping.items():
        src = signals.get(f"servo_{n}_pwm_us")
        if src is not None:
            signals[name] = Signal(name, src.t_s, src.values, "us", f"output {n}")
    if any(k.startswith("motor_") for k in mapping):
        vehicle = "quadrotor" if sum(k.startswith("motor_") for k in mapping) == 4 else "multirotor"
    elif "aileron_pwm_us" in mapping:
        vehicle = "fixed_wing"
    if "EV.Id" in signals:
        ev = signals["EV.Id"]
        state, ts, vs = 0.0, [0.0], [0.0]
        for t, i in zip(ev.t_s, ev.values, strict=True):
            if i in (EV_ARMED, EV_DISARMED):
                state = 1.0 if i == EV_ARMED else 0.0
                ts.append(t)
                vs.append(state)
        if len(ts) > 1:
            signals["armed"] = Signal("armed", np.array(ts), np.array(vs), "1", "from EV armed/disarmed events")
    return FlightLog(str(path), "dataflash", signals, params, vehicle, warnings)
