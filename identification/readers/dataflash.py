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

from identification.flightlog import FlightLog, LogError, Signal, add_battery

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
]


#: DataFlash format character -> (numpy dtype, multiplier) for the numeric columns (DFReader's FORMAT_TO_STRUCT)
NUMERIC_FORMATS: dict[str, tuple[str, float | None]] = {
    "b": ("i1", None), "B": ("u1", None), "h": ("<i2", None), "H": ("<u2", None), "i": ("<i4", None),
    "I": ("<u4", None), "f": ("<f4", None), "d": ("<f8", None), "c": ("<i2", 0.01), "C": ("<u2", 0.01),
    "e": ("<i4", 0.01), "E": ("<u4", 0.01), "L": ("<i4", 1e-7), "M": ("i1", None), "q": ("<i8", None),
    "Q": ("<u8", None), "g": ("<f2", None),
}
#: byte sizes of the non-numeric ones (strings, int16[32])
OTHER_SIZES = {"n": 4, "N": 16, "Z": 64, "a": 64}
HEAD1, HEAD2, FMT_ID, FMT_LEN = 0xA3, 0x95, 128, 89
SKIPPED = ("FMT", "FMTU", "UNIT", "MULT", "MSG")

Columns = dict[str, dict[str, np.ndarray]]


def _scan_binary(path: Path) -> tuple[Columns, dict[str, float], list[str]]:
    """Columns of every message type of a binary log, decoded with numpy per type.

    pymavlink's DFReader builds one Python object per message (about 30 us each: 2 s for a 5-minute log);
    here one pass finds the message offsets and numpy decodes each type's rows at once. Stops at the first
    damaged header, keeping what came before.
    """
    data = path.read_bytes()
    n = len(data)
    lengths: dict[int, int] = {FMT_ID: FMT_LEN}
    formats: dict[int, tuple[str, str, list[str]]] = {}
    offsets: dict[int, list[int]] = defaultdict(list)
    pos = 0
    while pos + 3 <= n:
        if data[pos] != HEAD1 or data[pos + 1] != HEAD2:
            break
        mid = data[pos + 2]
        length = lengths.get(mid)
        if length is None or pos + length > n:
            break
        if mid == FMT_ID:
            t_id, t_len = data[pos + 3], data[pos + 4]
            name = data[pos + 5:pos + 9].rstrip(b"\0").decode("ascii", "replace")
            fmt = data[pos + 9:pos + 25].rstrip(b"\0").decode("ascii", "replace")
            cols = data[pos + 25:pos + 89].rstrip(b"\0").decode("ascii", "replace").split(",")
            lengths[t_id] = t_len
            formats[t_id] = (name, fmt, cols)
        else:
            offsets[mid].append(pos)
        pos += length
    warnings = []
    if pos < n:
        warnings.append(f"{path}: {n - pos} of {n} bytes at the end could not be parsed and were dropped "
                        "(truncated or corrupt tail)")
    buf = np.frombuffer(data, dtype=np.uint8)
    out: Columns = {}
    params: dict[str, float] = {}
    for mid, offs in offsets.items():
        if mid not in formats:
            continue
        name, fmt, cols = formats[mid]
        fields, skip = [], 3
        for ch, col in zip(fmt, cols, strict=False):
            if ch in NUMERIC_FORMATS:
                fields.append((col, NUMERIC_FORMATS[ch][0], skip))
                skip += np.dtype(NUMERIC_FORMATS[ch][0]).itemsize
            elif ch in OTHER_SIZES:
                fields.append((col, f"S{OTHER_SIZES[ch]}", skip))
                skip += OTHER_SIZES[ch]
            else:
                warnings.append(f"{path}: message {name} has unknown format character {ch!r}; skipped")
                fields = []
                break
        if not fields or skip != lengths[mid]:
            continue
        dtype = np.dtype({"names": [f[0] for f in fields], "formats": [f[1] for f in fields],
                          "offsets": [f[2] for f in fields], "itemsize": lengths[mid]})
        idx = np.asarray(offs)[:, None] + np.arange(lengths[mid])
        rows = buf[idx].view(dtype).ravel()
        if name == "PARM":
            for pname, value in zip(rows["Name"], rows["Value"], strict=True):
                params[pname.rstrip(b"\0").decode("ascii", "replace")] = float(value)
            continue
        if name in SKIPPED:
            continue
        out[name] = {}
        for (col, _, _), ch in zip(fields, fmt, strict=False):
            if ch in NUMERIC_FORMATS:
                mul = NUMERIC_FORMATS[ch][1]
                v = rows[col].astype(float)
                out[name][col] = v * mul if mul else v
    return out, params, warnings


def _scan_text(path: Path) -> tuple[Columns, dict[str, float], list[str]]:
    """Text ``.log`` files through pymavlink's DFReader (rare, and small)."""
    try:
        reader = DFReader.DFReader_text(str(path))
    except (OSError, ValueError, IndexError, KeyError) as err:
        raise LogError(f"{path}: not a readable DataFlash log ({err})") from err
    rows: dict[str, list[dict]] = defaultdict(list)
    params: dict[str, float] = {}
    warnings = []
    while True:
        try:
            msg = reader.recv_msg()
        except (struct.error, ValueError, IndexError, KeyError) as err:
            warnings.append(f"{path}: stopped at a damaged message ({err})")
            break
        if msg is None:
            break
        mtype = msg.get_type()
        if mtype == "PARM":
            params[str(msg.Name)] = float(msg.Value)
        elif mtype not in SKIPPED:
            rows[mtype].append({k: v for k, v in msg.to_dict().items() if isinstance(v, int | float)})
    out: Columns = {}
    for mtype, rs in rows.items():
        out[mtype] = {k: np.array([r.get(k, np.nan) for r in rs], dtype=float) for k in rs[0]}
    return out, params, warnings


def _times(mtype: str, cols: dict[str, np.ndarray]) -> np.ndarray | None:
    """Boot time [s]. Old GPS messages carry GPS time of week in ``TimeMS`` and boot time in ``T``."""
    if mtype.startswith("GPS") and "T" in cols and "Week" in cols:
        return cols["T"] * 1e-3
    if "TimeUS" in cols:
        return cols["TimeUS"] * 1e-6
    if "TimeMS" in cols:
        return cols["TimeMS"] * 1e-3
    return None


def _battery(signals: dict[str, Signal]) -> None:
    """``BAT.Volt``/``BAT.Curr`` (V, A; ArduPilot 3.6+) else ``CURR.Volt``/``CURR.Curr`` (old logs: int16 in
    cV and cA, recognised by voltages above 100; ArduPilot logs 0 V when no monitor is fitted)."""
    for mtype in ("BAT", "CURR"):
        volt, curr = signals.get(f"{mtype}.Volt"), signals.get(f"{mtype}.Curr")
        if volt is None:
            continue
        v = volt.values
        positive = v[np.isfinite(v) & (v > 0)]
        scale = 0.01 if positive.size and np.median(positive) > 100.0 else 1.0
        add_battery(signals, volt.t_s, v * scale, None if curr is None else curr.values * scale, f"{mtype}.Volt")


def read_dataflash(path: Path, channel_map: dict[str, int] | None = None) -> FlightLog:
    """Read ``path``; a damaged tail yields the intact part and a warning saying how much was dropped.

    Messages with an instance column ``I`` (several IMUs, GPS receivers, ...) keep the first instance.
    """
    if not path.is_file():
        raise LogError(f"{path}: not a readable DataFlash log (file not found)")
    columns, params, warnings = _scan_binary(path) if path.suffix.lower() == ".bin" else _scan_text(path)
    timed: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]] = {}
    for mtype, cols in columns.items():
        t = _times(mtype, cols)
        if t is None or not len(t):
            continue
        inst = "I" if "I" in cols else "Inst" if "Inst" in cols else None
        if inst and len(cols[inst]):
            keep = cols[inst] == np.min(cols[inst])
            t, cols = t[keep], {k: v[keep] for k, v in cols.items()}
        timed[mtype] = (t, cols)
    if not timed:
        raise LogError(f"{path}: no timestamped messages found (empty or not a DataFlash log)")
    t0 = min(float(np.min(t)) for t, _ in timed.values())
    signals: dict[str, Signal] = {}
    for mtype, (t, cols) in timed.items():
        order = np.argsort(t, kind="stable")
        ts = t[order] - t0
        for fld, vals in cols.items():
            signals[f"{mtype}.{fld}"] = Signal(f"{mtype}.{fld}", ts, vals[order], "", f"raw {mtype}.{fld}")
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
    _battery(signals)
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
