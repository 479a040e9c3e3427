"""MAVLink telemetry logs (``.tlog``) through pymavlink: SERVO_OUTPUT_RAW, ATTITUDE, SCALED/RAW IMU,
GLOBAL_POSITION_INT, VFR_HUD, HEARTBEAT (armed), PARAM_VALUE."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import numpy as np
from pymavlink import mavutil

from identification.flightlog import FlightLog, LogError, Signal, add_battery

MAV_MODE_FLAG_SAFETY_ARMED = 128
G0 = 9.80665
UINT16_MAX = 65535

# canonical <- (message, field, scale)
FIELDS = [
    ("roll_rad", "ATTITUDE", "roll", 1.0), ("pitch_rad", "ATTITUDE", "pitch", 1.0), ("yaw_rad", "ATTITUDE", "yaw", 1.0),
    ("gyro_body_x_rad_s", "ATTITUDE", "rollspeed", 1.0), ("gyro_body_y_rad_s", "ATTITUDE", "pitchspeed", 1.0),
    ("gyro_body_z_rad_s", "ATTITUDE", "yawspeed", 1.0),
    ("accel_body_x_m_s2", "SCALED_IMU", "xacc", G0 / 1000), ("accel_body_y_m_s2", "SCALED_IMU", "yacc", G0 / 1000),
    ("accel_body_z_m_s2", "SCALED_IMU", "zacc", G0 / 1000),
    ("lat_deg", "GLOBAL_POSITION_INT", "lat", 1e-7), ("lon_deg", "GLOBAL_POSITION_INT", "lon", 1e-7),
    ("height_m", "GLOBAL_POSITION_INT", "alt", 1e-3), ("altitude_m", "GLOBAL_POSITION_INT", "relative_alt", 1e-3),
    ("vel_north_m_s", "GLOBAL_POSITION_INT", "vx", 0.01), ("vel_east_m_s", "GLOBAL_POSITION_INT", "vy", 0.01),
    ("vel_down_m_s", "GLOBAL_POSITION_INT", "vz", 0.01), ("airspeed_m_s", "VFR_HUD", "airspeed", 1.0),
    ("climb_rate_m_s", "VFR_HUD", "climb", 1.0),
]


def _cell_sum_mv(msg: object) -> float:
    """Pack voltage [mV] of a BATTERY_STATUS: the sum of its cells (UINT16_MAX marks an unused cell)."""
    cells = [c for c in list(getattr(msg, "voltages", [])) + list(getattr(msg, "voltages_ext", []) or [])
             if c not in (UINT16_MAX, 0)]
    return float(sum(cells)) if cells else math.nan


def _battery(signals: dict[str, Signal]) -> None:
    """SYS_STATUS.voltage_battery [mV] / current_battery [cA] (UINT16_MAX and -1: unknown), else the first
    BATTERY_STATUS (cells summed, current_battery [cA])."""
    for mtype, vkey in (("SYS_STATUS", "voltage_battery"), ("BATTERY_STATUS", "voltage_mV")):
        volt, curr = signals.get(f"{mtype}.{vkey}"), signals.get(f"{mtype}.current_battery")
        if volt is None:
            continue
        v = np.where(volt.values >= UINT16_MAX, np.nan, volt.values) * 1e-3
        c = None if curr is None else np.where(curr.values == -1, np.nan, curr.values) * 0.01
        add_battery(signals, volt.t_s, v, c, f"{mtype}.{vkey}")


def read_tlog(path: Path) -> FlightLog:
    try:
        conn = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    except (OSError, ValueError) as err:
        raise LogError(f"{path}: cannot open as a MAVLink telemetry log ({err})") from err
    rows: dict[str, list[tuple[float, dict]]] = defaultdict(list)
    params: dict[str, float] = {}
    bad = 0
    while True:
        try:
            msg = conn.recv_match()
        except (ValueError, IndexError, KeyError) as err:
            bad += 1
            if bad > 1000:
                raise LogError(f"{path}: too many undecodable MAVLink frames ({err})") from err
            continue
        if msg is None:
            break
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            bad += 1
            continue
        if mtype == "PARAM_VALUE":
            params[str(msg.param_id)] = float(msg.param_value)
            continue
        d = {k: v for k, v in msg.to_dict().items() if isinstance(v, int | float) and not isinstance(v, bool)}
        if mtype == "BATTERY_STATUS":
            d["voltage_mV"] = _cell_sum_mv(msg)
        rows[mtype].append((float(getattr(msg, "_timestamp", 0.0)), d))
    if not rows:
        raise LogError(f"{path}: no MAVLink messages found (empty or not a .tlog)")
    t0 = min(r[0][0] for r in rows.values())
    signals: dict[str, Signal] = {}
    for mtype, rr in rows.items():
        t = np.array([r[0] for r in rr]) - t0
        for fld in rr[0][1]:
            key = f"{mtype}.{fld}"
            signals[key] = Signal(key, t, np.array([r[1].get(fld, math.nan) for r in rr], float), "", f"raw {key}")
    for name, mtype, fld, scale in FIELDS:
        key = f"{mtype}.{fld}"
        if key in signals and name not in signals:
            s = signals[key]
            signals[name] = Signal(name, s.t_s, s.values * scale, "", f"from {key}")
    for n in range(1, 17):
        key = f"SERVO_OUTPUT_RAW.servo{n}_raw"
        if key in signals:
            s = signals[key]
            signals[f"servo_{n}_pwm_us"] = Signal(f"servo_{n}_pwm_us", s.t_s, s.values, "us", f"from {key}")
    _battery(signals)
    if "HEARTBEAT.base_mode" in signals:
        s = signals["HEARTBEAT.base_mode"]
        armed = (s.values.astype(int) & MAV_MODE_FLAG_SAFETY_ARMED) > 0
        signals["armed"] = Signal("armed", s.t_s, armed.astype(float), "1", "from HEARTBEAT.base_mode")
    warnings = [f"{path}: {bad} undecodable frame(s) skipped"] if bad else []
    return FlightLog(str(path), "tlog", signals, params, None, warnings)
