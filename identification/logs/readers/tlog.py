"""MAVLink telemetry logs (``.tlog``) through pymavlink: SERVO_OUTPUT_RAW, ATTITUDE, SCALED/RAW IMU,
GLOBAL_POSITION_INT, VFR_HUD, HEARTBEAT (armed), PARAM_VALUE."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import numpy as np
from pymavlink import mavutil

from fmu_models.common.units import DEGE7_TO_DEG, G0_M_S2
from identification.logs import flightlog
from identification.logs.flightlog import DataQuality, FlightLog, LogError, Signal, add_battery, sanitize_log

MAV_MODE_FLAG_SAFETY_ARMED = 128
UINT16_MAX = 65535
MAX_CONSECUTIVE_ERRORS = 1000

# canonical <- (message, field, scale)
FIELDS = [
    ("roll_rad", "ATTITUDE", "roll", 1.0), ("pitch_rad", "ATTITUDE", "pitch", 1.0), ("yaw_rad", "ATTITUDE", "yaw", 1.0),
    ("gyro_body_x_rad_s", "ATTITUDE", "rollspeed", 1.0), ("gyro_body_y_rad_s", "ATTITUDE", "pitchspeed", 1.0),
    ("gyro_body_z_rad_s", "ATTITUDE", "yawspeed", 1.0),
    ("accel_body_x_m_s2", "SCALED_IMU", "xacc", G0_M_S2 / 1000),
    ("accel_body_y_m_s2", "SCALED_IMU", "yacc", G0_M_S2 / 1000),
    ("accel_body_z_m_s2", "SCALED_IMU", "zacc", G0_M_S2 / 1000),
    ("lat_deg", "GLOBAL_POSITION_INT", "lat", DEGE7_TO_DEG), ("lon_deg", "GLOBAL_POSITION_INT", "lon", DEGE7_TO_DEG),
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


def _read_messages(conn: object, path: Path, quality: DataQuality
                   ) -> tuple[dict[str, list[tuple[float, dict]]], dict[str, float], list[str]]:
    """Every decodable message by type as ``(time [s], numeric fields)``; undecodable frames are counted
    (their bytes as skipped); reading stops after ``MAX_CONSECUTIVE_ERRORS`` exceptions in a row."""
    rows: dict[str, list[tuple[float, dict]]] = defaultdict(list)
    params: dict[str, float] = {}
    warnings: list[str] = []
    errors = 0
    while True:
        try:
            msg = conn.recv_match()  # type: ignore[attr-defined]
            if msg is None:
                break
            mtype = msg.get_type()
            quality.messages_total += 1
            if mtype == "BAD_DATA":
                nbytes = len(msg.get_msgbuf() or b"")
                quality.add_damage(int(getattr(conn, "offset", 0) or 0) - nbytes, nbytes)
                continue
            if mtype == "PARAM_VALUE":
                params[str(msg.param_id).rstrip("\0")] = float(msg.param_value)
                continue
            d = {k: v for k, v in msg.to_dict().items() if isinstance(v, int | float) and not isinstance(v, bool)}
            if mtype == "BATTERY_STATUS":
                d["voltage_mV"] = _cell_sum_mv(msg)
            rows[mtype].append((float(getattr(msg, "_timestamp", 0.0)), d))
            errors = 0
        except Exception as err:  # pymavlink raises many kinds on damaged frames
            quality.messages_total += 1
            quality.messages_skipped += 1
            errors += 1
            if errors > MAX_CONSECUTIVE_ERRORS:
                warnings.append(f"{path}: stopped after {errors} undecodable frames in a row ({err}); "
                                "the messages before were kept")
                break
    if quality.messages_skipped:
        warnings.append(f"{path}: {quality.messages_skipped} undecodable frame(s) skipped")
    return rows, params, warnings


def read_tlog(path: Path) -> FlightLog:
    try:
        conn = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    except Exception as err:  # pymavlink raises bare exceptions on unreadable files
        raise LogError(f"{path}: cannot open as a MAVLink telemetry log ({type(err).__name__}: {err})") from err
    quality = DataQuality(str(path))
    quality.bytes_total = path.stat().st_size
    try:
        rows, params, warnings = _read_messages(conn, path, quality)
    finally:
        conn.close()
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
    log = sanitize_log(FlightLog(str(path), "tlog", signals, params, None, warnings), quality)
    flightlog.true_airspeed(log, "VFR_HUD.airspeed")  # MAVLink: calibrated or indicated; ArduPilot: its EAS
    return log
