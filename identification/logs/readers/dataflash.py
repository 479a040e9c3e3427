"""ArduPilot DataFlash logs (binary ``.bin`` and text ``.log``) through pymavlink's DFReader.

Handles the old ``TimeMS`` and the newer ``TimeUS`` time stamps, maps vendor messages to the canonical
signals of docs/interfaces.md, keeps every raw field as ``MSG.Field`` and the PARM parameters.
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from fmu_models.common.units import DEG_TO_RAD, DEGE7_TO_DEG, LOG_UNITS
from fmu_models.quadrotor.constants import N_MOTORS
from identification.logs import flightlog
from identification.logs.flightlog import DataQuality, FlightLog, LogError, Signal, add_battery, sanitize_log

#: ArduPilot SERVOn_FUNCTION values
MOTOR_FUNCTIONS = {33: 1, 34: 2, 35: 3, 36: 4, 37: 5, 38: 6, 39: 7, 40: 8}
SURFACE_FUNCTIONS = {4: "aileron", 19: "elevator", 70: "throttle", 21: "rudder"}
#: ArduPilot EV ids: 10 armed, 11 disarmed
EV_ARMED, EV_DISARMED = 10, 11

#: ArduCopter RATE's achieved body rate field per body axis (the target is the field + "Des")
RATE_AXES = (("x", "R"), ("y", "P"), ("z", "Y"))
# canonical name <- (message, field, scale to SI, unit)
CANONICAL: list[tuple[str, str, str, float, str]] = [
    ("accel_body_x_m_s2", "IMU", "AccX", 1.0, "m/s2"),
    ("accel_body_y_m_s2", "IMU", "AccY", 1.0, "m/s2"),
    ("accel_body_z_m_s2", "IMU", "AccZ", 1.0, "m/s2"),
    ("gyro_body_x_rad_s", "IMU", "GyrX", 1.0, "rad/s"),
    ("gyro_body_y_rad_s", "IMU", "GyrY", 1.0, "rad/s"),
    ("gyro_body_z_rad_s", "IMU", "GyrZ", 1.0, "rad/s"),
    # without an IMU message, the rates ArduCopter's rate controller feeds back (RATE R, P, Y [deg/s]: the AHRS's
    # bias-corrected gyro)
    *((f"gyro_body_{axis}_rad_s", "RATE", fld, DEG_TO_RAD, "rad/s") for axis, fld in RATE_AXES),
    ("roll_rad", "ATT", "Roll", DEG_TO_RAD, "rad"),
    ("pitch_rad", "ATT", "Pitch", DEG_TO_RAD, "rad"),
    ("yaw_rad", "ATT", "Yaw", DEG_TO_RAD, "rad"),
    ("lat_deg", "GPS", "Lat", 1.0, "deg"),
    ("lon_deg", "GPS", "Lng", 1.0, "deg"),
    ("height_m", "GPS", "Alt", 1.0, "m"),
    ("altitude_m", "CTUN", "Alt", 1.0, "m"),
    ("airspeed_m_s", "ARSP", "Airspeed", 1.0, "m/s"),
    # ArduCopter's rate controller (AC_AttitudeControl, RATE: TimeUS,RDes,R,ROut,PDes,P,POut,YDes,Y,YOut,ADes,A,
    # AOut; units deg/s, normalised outputs, vertical accelerations in cm/s/s, up positive, gravity removed)
    *((f"rate_target_body_{axis}_rad_s", "RATE", f"{fld}Des", DEG_TO_RAD, "rad/s") for axis, fld in RATE_AXES),
    *((f"rate_achieved_body_{axis}_rad_s", "RATE", fld, DEG_TO_RAD, "rad/s") for axis, fld in RATE_AXES),
    ("rate_out_roll", "RATE", "ROut", 1.0, "1"),
    ("rate_out_pitch", "RATE", "POut", 1.0, "1"),
    ("rate_out_yaw", "RATE", "YOut", 1.0, "1"),
    ("throttle_out", "RATE", "AOut", 1.0, "1"),
    ("accel_target_up_m_s2", "RATE", "ADes", LOG_UNITS["cm/s2"][1], "m/s2"),
    ("accel_up_m_s2", "RATE", "A", LOG_UNITS["cm/s2"][1], "m/s2"),
]
#: the rate controller's outputs to the motor mixer (RATE ROut, POut, YOut, AOut; -1..1, throttle 0..1)
RATE_OUTPUTS = ("rate_out_roll", "rate_out_pitch", "rate_out_yaw", "throttle_out")


#: DataFlash format character -> (numpy dtype, multiplier) for the numeric columns (DFReader's FORMAT_TO_STRUCT)
NUMERIC_FORMATS: dict[str, tuple[str, float | None]] = {
    "b": ("i1", None), "B": ("u1", None), "h": ("<i2", None), "H": ("<u2", None), "i": ("<i4", None),
    "I": ("<u4", None), "f": ("<f4", None), "d": ("<f8", None), "c": ("<i2", 0.01), "C": ("<u2", 0.01),
    "e": ("<i4", 0.01), "E": ("<u4", 0.01), "L": ("<i4", DEGE7_TO_DEG), "M": ("i1", None), "q": ("<i8", None),
    "Q": ("<u8", None), "g": ("<f2", None),
}
#: byte sizes of the non-numeric ones (strings, int16[32])
OTHER_SIZES = {"n": 4, "N": 16, "Z": 64, "a": 64}
HEAD1, HEAD2, FMT_ID, FMT_LEN = 0xA3, 0x95, 128, 89
SKIPPED = ("FMT", "FMTU", "UNIT", "MULT", "MSG")

Columns = dict[str, dict[str, np.ndarray]]


HEADER = bytes((HEAD1, HEAD2))


def _resync(data: bytes, start: int, lengths: dict[int, int]) -> int:
    """Offset of the next plausible message at or after ``start``: the two sync bytes, a known type, and the
    next message's sync bytes right after its length (or the end of the file); ``len(data)`` when none."""
    n = len(data)
    p = data.find(HEADER, start)
    while p != -1 and p + 3 <= n:
        length = lengths.get(data[p + 2])
        if length is not None:
            end = p + length
            if end == n or (end + 2 <= n and data[end] == HEAD1 and data[end + 1] == HEAD2):
                return p
        p = data.find(HEADER, p + 1)
    return n


def _walk(data: bytes, quality: DataQuality) -> tuple[dict[int, tuple[str, str, list[str]]], dict[int, int],
                                                      dict[int, list[int]], int]:
    """Message offsets by type. A message counts when its type is known and the next message (or the end of
    the file) follows right after it, or when it does not overlap the next plausible message (damage right
    after it); otherwise the bytes up to the next plausible message are skipped and counted
    (resynchronisation), so one damaged byte costs about one message, not the rest of the log."""
    n = len(data)
    buf = np.frombuffer(data, dtype=np.uint8)
    # sync-byte pairs marked once with numpy (1 at each 0xA3 0x95; 1 at n: the end also closes a message)
    mark = np.zeros(n + 256, dtype=np.uint8)
    mark[:n - 1] = (buf[:-1] == HEAD1) & (buf[1:] == HEAD2)
    mark[n] = 1
    is_sync = mark.tobytes()
    lengths: dict[int, int] = {FMT_ID: FMT_LEN}
    table = [0] * 256  # the same lengths as a list (0: unknown type), for the hot loop
    table[FMT_ID] = FMT_LEN
    formats: dict[int, tuple[str, str, list[str]]] = {}
    offsets: dict[int, list[int]] = defaultdict(list)
    pos, count = 0, 0
    while pos + 3 <= n:
        length = table[data[pos + 2]] if is_sync[pos] else 0
        end = pos + length
        if length and end <= n and is_sync[end]:
            count += 1
            if length == FMT_LEN and data[pos + 2] == FMT_ID:
                _define(data, pos, lengths, formats, table)
            else:
                offsets[data[pos + 2]].append(pos)
            pos = end
            continue
        nxt = _resync(data, pos + 1, lengths)
        if length and end <= nxt:  # intact message followed by damage: keep it (no overlap)
            count += 1
            if data[pos + 2] == FMT_ID:
                _define(data, pos, lengths, formats, table)
            else:
                offsets[data[pos + 2]].append(pos)
            pos = end
            if nxt == pos:
                continue
        quality.add_damage(pos, nxt - pos, max(1, data.count(HEADER, pos, nxt)))
        pos = nxt
    if pos < n:
        quality.add_damage(pos, n - pos)
    quality.messages_total = count + quality.messages_skipped
    return formats, lengths, offsets, count


def _define(data: bytes, pos: int, lengths: dict[int, int], formats: dict[int, tuple[str, str, list[str]]],
            table: list[int]) -> None:
    """Record one FMT message; a type already defined keeps its first definition (a damaged FMT cannot
    redefine it), a length too short for the header is ignored."""
    t_id, t_len = data[pos + 3], data[pos + 4]
    if t_id in lengths or t_len < 3:
        return
    name = data[pos + 5:pos + 9].rstrip(b"\0").decode("ascii", "replace")
    fmt = data[pos + 9:pos + 25].rstrip(b"\0").decode("ascii", "replace")
    cols = data[pos + 25:pos + 89].rstrip(b"\0").decode("ascii", "replace").split(",")
    lengths[t_id] = table[t_id] = t_len
    formats[t_id] = (name, fmt, cols)


def _row_dtype(name: str, fmt: str, cols: list[str], length: int) -> np.dtype | None:
    """numpy record layout of one message type, or None when the FMT does not describe ``length`` bytes."""
    fields, skip = [], 3
    if len(fmt) != len(cols) or len(set(cols)) != len(cols):
        return None
    for ch, col in zip(fmt, cols, strict=True):
        if ch in NUMERIC_FORMATS:
            size, kind = np.dtype(NUMERIC_FORMATS[ch][0]).itemsize, NUMERIC_FORMATS[ch][0]
        elif ch in OTHER_SIZES:
            size, kind = OTHER_SIZES[ch], f"S{OTHER_SIZES[ch]}"
        else:
            return None
        fields.append((col, kind, skip))
        skip += size
    if not fields or skip != length:
        return None
    try:
        return np.dtype({"names": [f[0] for f in fields], "formats": [f[1] for f in fields],
                         "offsets": [f[2] for f in fields], "itemsize": length})
    except (ValueError, TypeError):
        return None


def _scan_binary(path: Path, quality: DataQuality) -> tuple[Columns, dict[str, float], list[str]]:
    """Columns of every message type of a binary log, decoded with numpy per type.

    pymavlink's DFReader builds one Python object per message (about 30 us each: 2 s for a 5-minute log);
    here one pass finds the message offsets and numpy decodes each type's rows at once. Damaged stretches are
    skipped up to the next plausible message and counted in ``quality``.
    """
    data = path.read_bytes()
    quality.bytes_total = len(data)
    formats, lengths, offsets, _ = _walk(data, quality)
    warnings = []
    buf = np.frombuffer(data, dtype=np.uint8)
    out: Columns = {}
    params: dict[str, float] = {}
    for mid, offs in offsets.items():
        if mid not in formats:
            continue
        name, fmt, cols = formats[mid]
        dtype = _row_dtype(name, fmt, cols, lengths[mid])
        if dtype is None:
            warnings.append(f"{path}: message {name} has a format {fmt!r} that does not fit its length; skipped")
            continue
        idx = np.asarray(offs)[:, None] + np.arange(lengths[mid])
        rows = buf[idx].view(dtype).ravel()
        if name == "PARM":
            kinds = dict(zip(cols, fmt, strict=True))
            if kinds.get("Name") in OTHER_SIZES and kinds.get("Value") in NUMERIC_FORMATS:
                for pname, value in zip(rows["Name"], rows["Value"], strict=True):
                    params[pname.rstrip(b"\0").decode("ascii", "replace")] = float(value)
            else:
                warnings.append(f"{path}: PARM has an unexpected format {fmt!r} ({','.join(cols)}); parameters skipped")
            continue
        if name in SKIPPED:
            continue
        out[name] = {}
        for col, ch in zip(cols, fmt, strict=True):
            if ch in NUMERIC_FORMATS:
                mul = NUMERIC_FORMATS[ch][1]
                with np.errstate(invalid="ignore", over="ignore"):
                    v = rows[col].astype(float)
                out[name][col] = v * mul if mul else v
    if quality.bytes_skipped:
        warnings.append(f"{path}: {quality.bytes_skipped} of {len(data)} bytes could not be parsed and were "
                        f"skipped ({quality.messages_skipped} damaged message(s)); the rest was kept")
    return out, params, warnings


def _scan_text(path: Path, quality: DataQuality) -> tuple[Columns, dict[str, float], list[str]]:
    """Text ``.log`` files (``NAME, v1, v2, ...`` lines after their ``FMT`` lines); bad lines are skipped
    and counted."""
    raw = path.read_bytes()
    quality.bytes_total = len(raw)
    formats: dict[str, tuple[str, list[str]]] = {}
    rows: dict[str, list[list[float]]] = defaultdict(list)
    params: dict[str, float] = {}
    offset = 0
    for line in raw.split(b"\n"):
        size = len(line) + 1
        text = line.decode("ascii", "replace").strip()
        offset += size
        if not text:
            continue
        quality.messages_total += 1
        if not _text_line(text, formats, rows, params):
            quality.add_damage(offset - size, size)
    out: Columns = {}
    for name, rs in rows.items():
        fmt, cols = formats[name]
        arr = np.array(rs, dtype=float).reshape(-1, len(cols))
        out[name] = {c: arr[:, j] for j, (c, ch) in enumerate(zip(cols, fmt, strict=True)) if ch not in "nNZa"}
    warnings = []
    if quality.messages_skipped:
        warnings.append(f"{path}: {quality.messages_skipped} damaged line(s) skipped")
    return out, params, warnings


def _text_line(text: str, formats: dict[str, tuple[str, list[str]]], rows: dict[str, list[list[float]]],
               params: dict[str, float]) -> bool:
    """Parse one text line into ``formats``/``rows``/``params``; False when it is damaged."""
    parts = [p.strip() for p in text.split(",")]
    name = parts[0]
    if name == "FMT":
        if len(parts) < 6 or not parts[3] or len(parts[4]) != len(parts) - 5:
            return False
        if parts[3] not in formats and all(ch in NUMERIC_FORMATS or ch in OTHER_SIZES for ch in parts[4]):
            formats[parts[3]] = (parts[4], parts[5:])
        return True
    if name not in formats:
        return name in SKIPPED
    fmt, cols = formats[name]
    if len(parts) - 1 != len(cols):
        return False
    values = []
    try:
        for ch, v in zip(fmt, parts[1:], strict=True):
            values.append(math.nan if ch in "nNZa" else float(v))
    except ValueError:
        return False
    if name == "PARM" and "Name" in cols and "Value" in cols:
        params[parts[1 + cols.index("Name")]] = values[cols.index("Value")]
    elif name not in SKIPPED:
        rows[name].append(values)
    return True


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
    quality = DataQuality(str(path))
    with path.open("rb") as fh:
        binary = path.suffix.lower() == ".bin" or fh.read(2) == HEADER
    columns, params, warnings = (_scan_binary if binary else _scan_text)(path, quality)
    signals = _raw_signals(_first_instance_timed(columns, path))
    _derived_signals(signals)
    vehicle = _mapped_outputs(signals, params, channel_map)
    _armed(signals)
    log = sanitize_log(FlightLog(str(path), "dataflash", signals, params, vehicle, warnings), quality)
    flightlog.true_airspeed(log, "ARSP.Airspeed")
    return log


def _first_instance_timed(columns: Columns, path: Path) -> dict[str, tuple[np.ndarray, dict[str, np.ndarray]]]:
    """Per message type its times [s] and columns, first instance only; LogError when nothing is timed."""
    timed: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]] = {}
    for mtype, cols in columns.items():
        t = _times(mtype, cols)
        if t is None or not len(t):
            continue
        inst = "I" if "I" in cols else "Inst" if "Inst" in cols else None
        if inst and len(cols[inst]):
            keep = cols[inst] == np.nanmin(cols[inst])
            t, cols = t[keep], {k: v[keep] for k, v in cols.items()}
        timed[mtype] = (t, cols)
    if not timed:
        raise LogError(f"{path}: no timestamped messages found (empty or not a DataFlash log)")
    return timed


def _raw_signals(timed: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]]) -> dict[str, Signal]:
    """``MTYPE.Field`` signals, times from the log's first sample, in file order."""
    starts = [float(np.min(t[np.isfinite(t)])) for t, _ in timed.values() if np.isfinite(t).any()]
    t0 = min(starts) if starts else 0.0
    signals: dict[str, Signal] = {}
    for mtype, (t, cols) in timed.items():
        ts = t - t0  # file order: sanitize_log sorts and cleans the time axis
        for fld, vals in cols.items():
            signals[f"{mtype}.{fld}"] = Signal(f"{mtype}.{fld}", ts, vals, "", f"raw {mtype}.{fld}")
    return signals


def _derived_signals(signals: dict[str, Signal]) -> None:
    """Add the canonical signals (SI units), NED velocity, battery, altitude, climb rate and servo outputs."""
    for name, mtype, fld, scale, unit in CANONICAL:
        key = f"{mtype}.{fld}"
        if key in signals and name not in signals:
            s = signals[key]
            signals[name] = Signal(name, s.t_s, s.values * scale, unit, f"from {key}")
    if all(f"GPS.{f}" in signals for f in ("Spd", "GCrs", "VZ")):  # ground speed, course [deg], VZ down (NED)
        spd, crs, vz = (signals[f"GPS.{f}"] for f in ("Spd", "GCrs", "VZ"))
        course = crs.values * DEG_TO_RAD
        for name, vals in (("vel_north_m_s", spd.values * np.cos(course)),
                           ("vel_east_m_s", spd.values * np.sin(course)), ("vel_down_m_s", vz.values)):
            signals[name] = Signal(name, spd.t_s, vals, "m/s", "from GPS.Spd/GCrs/VZ")
    # without GPS velocity, the EKF3's NED velocity (XKF1 VN, VE, VD [m/s], first core)
    if all(f"XKF1.{f}" in signals for f in ("VN", "VE", "VD")):
        for name, fld in (("vel_north_m_s", "VN"), ("vel_east_m_s", "VE"), ("vel_down_m_s", "VD")):
            if name not in signals:
                v = signals[f"XKF1.{fld}"]
                signals[name] = Signal(name, v.t_s, v.values, "m/s", f"from XKF1.{fld}")
    _battery(signals)
    if "altitude_m" not in signals and "BARO.Alt" in signals:
        s = signals["BARO.Alt"]
        signals["altitude_m"] = Signal("altitude_m", s.t_s, s.values, "m", "from BARO.Alt")
    if "CTUN.CRt" in signals:
        s = signals["CTUN.CRt"]
        scale = 0.01 if np.nanpercentile(np.abs(s.values), 99) > 50 else 1.0  # cm/s (robust to a bad sample)
        signals["climb_rate_m_s"] = Signal("climb_rate_m_s", s.t_s, s.values * scale, "m/s", "from CTUN.CRt")
    # servo outputs: RCOU C1.. (new) or Ch1.. (old)
    for n in range(1, 33):
        for key in (f"RCOU.C{n}", f"RCOU.Ch{n}"):
            if key in signals:
                s = signals[key]
                signals[f"servo_{n}_pwm_us"] = Signal(f"servo_{n}_pwm_us", s.t_s, s.values, "us", f"from {key}")
                break


def _mapped_outputs(
    signals: dict[str, Signal], params: dict[str, float], channel_map: dict[str, int] | None
) -> str | None:
    """Add motor/surface PWM signals from ``SERVOn_FUNCTION`` (and ``channel_map``); return the vehicle kind."""
    functions = {n: int(params[f"SERVO{n}_FUNCTION"]) for n in range(1, 33) if f"SERVO{n}_FUNCTION" in params}
    mapping: dict[str, int] = {}
    if functions:
        for n, fn in functions.items():
            if fn in MOTOR_FUNCTIONS:
                mapping[f"motor_{MOTOR_FUNCTIONS[fn]}_pwm_us"] = n
            elif fn in SURFACE_FUNCTIONS:
                mapping[f"{SURFACE_FUNCTIONS[fn]}_pwm_us"] = n
    elif "FRAME" in params or any(k.startswith("MOT_") for k in params):
        mapping = {f"motor_{k}_pwm_us": k for k in range(1, N_MOTORS + 1)}  # old ArduCopter: motors on outputs 1-4
    mapping.update(channel_map or {})
    for name, n in mapping.items():
        src = signals.get(f"servo_{n}_pwm_us")
        if src is not None:
            signals[name] = Signal(name, src.t_s, src.values, "us", f"output {n}")
    if any(k.startswith("motor_") for k in mapping):
        return "quadrotor" if sum(k.startswith("motor_") for k in mapping) == 4 else "multirotor"
    if "aileron_pwm_us" in mapping:
        return "fixed_wing"
    return None


def _armed(signals: dict[str, Signal]) -> None:
    """Add ``armed`` (0/1, from 0 at the start) from the EV armed/disarmed events, when there are any."""
    if "EV.Id" not in signals:
        return
    ev = signals["EV.Id"]
    state, ts, vs = 0.0, [0.0], [0.0]
    for t, i in zip(ev.t_s, ev.values, strict=True):
        if i in (EV_ARMED, EV_DISARMED):
            state = 1.0 if i == EV_ARMED else 0.0
            ts.append(t)
            vs.append(state)
    if len(ts) > 1:
        signals["armed"] = Signal("armed", np.array(ts), np.array(vs), "1", "from EV armed/disarmed events")
