"""PX4 ULog exported by pyulog's ``ulog2csv``: a folder of ``<flight>_<topic>_<instance>.csv`` files.

Every CSV has a ``timestamp`` column (us, boot clock); the files are joined on it by naming each column
``<topic>[_<instance>].<field>`` (as the ULog reader names raw fields) and aliasing the same canonical
signals as :mod:`identification.logs.readers.ulog`: accelerometer/gyro, attitude, motor PWM
(``motor_<k>_pwm_us`` from ``actuator_outputs`` outputs 0..3), ``battery_voltage_v`` (from
``voltage_filtered_v`` where logged, else ``voltage_v``) and ``battery_current_a``. PWM at or below
``DISARMED_PWM_US`` marks the vehicle disarmed (PX4 writes PWM_DISARMED, 900 us), which gives ``armed``.
A damaged CSV keeps its readable rows; what was lost goes to ``FlightLog.warnings``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from fmu_models.quadrotor.constants import N_MOTORS  # PX4 quadrotor: motors on actuator outputs 0..3
from identification.logs.flightlog import FlightLog, LogError, Signal
from identification.logs.readers.px4_signals import add_imu_and_attitude, add_local_position, add_outputs, alias

DISARMED_PWM_US = 950.0  #: PX4 PWM_DISARMED is 900 us; anything at or below this is "motors off"
_NAME = re.compile(r"^(?P<flight>.+?)_(?P<topic>[a-z][a-z0-9_]*?)_(?P<inst>\d+)$")
_TOPICS = (
    "actuator_outputs",
    "actuator_controls_0",
    "actuator_controls",
    "sensor_combined",
    "battery_status",
    "vehicle_attitude",
    "vehicle_local_position",
    "vehicle_status",
    "input_rc",
)


def _topic_of(stem: str) -> tuple[str, int] | None:
    """``(topic, instance)`` of a ``<flight>_<topic>_<instance>`` file stem, or None."""
    for topic in _TOPICS:
        m = re.search(rf"_{topic}_(\d+)$", stem)
        if m:
            return topic, int(m.group(1))
    m = _NAME.match(stem)
    return (m.group("topic"), int(m.group("inst"))) if m else None


def _read_csv(path: Path, warnings: list[str]) -> tuple[list[str], np.ndarray]:
    """Header and float rows of one CSV; rows that do not parse are dropped (and counted)."""
    lines = path.read_text(errors="replace").splitlines()
    if not lines:
        raise LogError(f"{path}: empty CSV (no header)")
    header = [h.strip() for h in lines[0].split(",")]
    if "timestamp" not in header:
        raise LogError(f"{path}: no 'timestamp' column (pyulog ulog2csv output has one); header {header[:6]}")
    rows, bad = [], 0
    for line in lines[1:]:
        parts = line.split(",")
        if len(parts) != len(header):
            bad += 1
            continue
        try:
            rows.append([float(v) for v in parts])
        except ValueError:
            bad += 1
    if bad:
        warnings.append(f"{path}: {bad} malformed row(s) dropped, {len(rows)} kept")
    return header, np.asarray(rows, dtype=float).reshape(-1, len(header))


def read_px4_csv(folder: Path) -> FlightLog:
    """Read a pyulog ``ulog2csv`` folder into a :class:`FlightLog` (time from the earliest timestamp)."""
    folder = Path(folder)
    files = sorted(folder.glob("*.csv"))
    if not files:
        raise LogError(f"{folder}: no CSV files (expected pyulog ulog2csv output <flight>_<topic>_<n>.csv)")
    warnings: list[str] = []
    tables: dict[str, tuple[list[str], np.ndarray]] = {}
    for f in files:
        ti = _topic_of(f.stem)
        if ti is None:
            warnings.append(f"{f}: name is not <flight>_<topic>_<instance>.csv; skipped")
            continue
        topic, inst = ti
        tables[topic if inst == 0 else f"{topic}_{inst}"] = _read_csv(f, warnings)
    starts = [tab[1][:, tab[0].index("timestamp")].min() for tab in tables.values() if tab[1].size]
    if not starts:
        raise LogError(f"{folder}: the CSV files hold no data rows")
    t0 = float(min(starts))
    signals: dict[str, Signal] = {}
    for prefix, (header, data) in tables.items():
        ts = data[:, header.index("timestamp")]
        order = np.argsort(ts, kind="stable")
        t = (ts[order] - t0) * 1e-6
        for j, name in enumerate(header):
            if name != "timestamp":
                key = f"{prefix}.{name}"
                signals[key] = Signal(key, t, data[order, j], "", f"raw {key}")
    _aliases(signals, folder, warnings)
    vehicle = "quadrotor" if "motor_1_pwm_us" in signals else None
    return FlightLog(str(folder), "px4_csv", signals, {}, vehicle, warnings)


def _aliases(signals: dict[str, Signal], folder: Path, warnings: list[str]) -> None:
    """Canonical names (as the ULog reader gives them) from the raw topic fields."""
    add_imu_and_attitude(signals)
    add_local_position(signals)
    _battery(signals, folder, warnings)
    add_outputs(signals, N_MOTORS)
    if "motor_1_pwm_us" in signals and "armed" not in signals:
        s = signals["motor_1_pwm_us"]
        pwm = np.stack([signals[f"motor_{k}_pwm_us"].resample(s.t_s) for k in range(1, N_MOTORS + 1)])
        armed = (pwm > DISARMED_PWM_US).any(axis=0).astype(float)
        signals["armed"] = Signal("armed", s.t_s, armed, "1", f"motor PWM above {DISARMED_PWM_US} us")


def _battery(signals: dict[str, Signal], folder: Path, warnings: list[str]) -> None:
    """``battery_voltage_v`` (filtered where it holds valid values, else raw) and ``battery_current_a``.

    Values are passed on as logged; users of the voltage check it (an all-zero column is an error there).
    """
    keys = [k for k in ("battery_status.voltage_filtered_v", "battery_status.voltage_v") if k in signals]
    valid = [k for k in keys if np.any(np.isfinite(signals[k].values) & (signals[k].values > 0.0))]
    if keys and not valid:
        warnings.append(f"{folder}: {', '.join(keys)} are zero or NaN in every row")
    if keys:
        alias(signals, "battery_voltage_v", (valid or keys)[0], "V")
    alias(signals, "battery_current_a", "battery_status.current_a", "A")
