"""Robustness, log family: hypothesis-generated damage for every log format.

A small synthetic log of each format (DataFlash binary written by identification.logs.dataflash_writer, DataFlash text,
MAVLink tlog packed by pymavlink, ULog written here to the ULog spec, CSV) is built with or without a time
jump (+1 h, +1e6 s, +1e9 s, -5 s), then damaged: bit flips, truncation, duplicated blocks, swapped (reordered)
blocks, overwritten and inserted junk. Reading it must either give a FlightLog whose time axes are finite and
ordered, whose duration stays bounded (no grid across a jump), with a JSON-ready, bounded DataQuality, or raise
:class:`LogError` naming the file. Any other exception (a traceback) or a read longer than ``HANG_S`` fails.
At least 1000 examples in all; the counts per family are printed.
"""

from __future__ import annotations

import functools
import json
import math
import os
import signal
import struct
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from identification.logs.flightlog import JUMP_S, FlightLog, LogError
from identification.logs.readers import read_log

#: examples per family (1900 in all; each read takes a few ms: about 40 s on 2 cores)
#: ``UAVFMU_FUZZ_SCALE`` (0..1, default 1) shrinks the example counts for `make mutation` only, where the suite
#: runs once per mutant; CI and `make test` run the full counts
FUZZ_SCALE = min(1.0, max(0.01, float(os.environ.get("UAVFMU_FUZZ_SCALE", "1"))))
EXAMPLES = {k: max(5, round(n * FUZZ_SCALE))
            for k, n in {"dataflash_bin": 500, "dataflash_text": 300, "tlog": 400, "ulog": 300, "csv": 400}.items()}
HANG_S = 10.0  #: a single read longer than this is a hang
DURATION_S = 5.0  #: length of the synthetic flights
T0_S = 10.0  #: their first time stamp
JUMPS = [None, 3600.0, 1e6, 1e9, -5.0]  #: time jumps inserted 60 % into the log (None: none)
COUNTS: Counter[str] = Counter()
#: share of its examples each family must run in its own test (hypothesis stops early only on an exhausted
#: strategy; the 1900 examples keep at least 1000 in all at this share)
MIN_SHARE = 0.9
FUZZ = dict(deadline=None, database=None, derandomize=False,
            suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                   HealthCheck.data_too_large])


@pytest.fixture(scope="module", autouse=True)
def _print_counts() -> Iterator[None]:
    yield
    total = sum(COUNTS.values())
    print("\ndamaged-log robustness examples: " + ", ".join(f"{k} {v}" for k, v in sorted(COUNTS.items()))
          + f"; total {total}")


def _times(rate_hz: float, jump: float | None) -> np.ndarray:
    t = np.arange(int(DURATION_S * rate_hz)) / rate_hz + T0_S
    if jump is not None:
        t = np.where(t >= T0_S + 0.6 * DURATION_S, t + jump, t)
    return t


# ----------------------------------------------------------------------------------------------- builders
def _dataflash_bin(path: Path, jump: float | None) -> Path:
    from identification.logs.dataflash_writer import MessageLayout, write_log

    t_imu, t_slow = _times(50.0, jump), _times(10.0, jump)
    bat = MessageLayout("BAT", "QBff", "TimeUS,Inst,Volt,Curr")
    streams = {
        "IMU": (t_imu, {"I": 0, "GyrX": np.sin(t_imu), "AccZ": -9.8 + 0.01 * np.cos(t_imu)}),
        "ATT": (t_slow, {"Roll": 5 * np.sin(t_slow), "Yaw": 10.0}),
        "RCOU": (t_slow, {f"C{k}": 1500 + k for k in range(1, 5)}),
        "BAT": (t_slow, {"Inst": 0, "Volt": 12.0, "Curr": 5.0}),
        "EV": ([T0_S + 1.0, T0_S + 2.0], {"Id": [10, 11]}),
    }
    return write_log(path, streams, params={"FRAME": 1.0, "SERVO1_FUNCTION": 33.0}, layouts=[bat])


def _dataflash_text(path: Path, jump: float | None) -> Path:
    lines = ["FMT, 128, 89, FMT, BBnNZ, Type,Length,Name,Format,Columns",
             "FMT, 129, 31, IMU, Qffffff, TimeUS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ",
             "FMT, 130, 40, PARM, QNf, TimeUS,Name,Value",
             "FMT, 131, 20, RCOU, QHHHH, TimeUS,C1,C2,C3,C4",
             "PARM, 0, FRAME, 1"]
    for t in _times(20.0, jump):
        lines.append(f"IMU, {int(t * 1e6)}, 0.01, 0.02, 0.03, 0.1, 0.2, -9.8")
        lines.append(f"RCOU, {int(t * 1e6)}, 1500, 1510, 1520, 1530")
    path.write_text("\n".join(lines) + "\n")
    return path


def _tlog(path: Path, jump: float | None) -> Path:
    from pymavlink.dialects.v20 import ardupilotmega as mav

    link = mav.MAVLink(None, srcSystem=1)
    with path.open("wb") as fh:
        for k, t in enumerate(_times(20.0, jump)):
            t_us = int((1_700_000_000 + t) * 1e6)
            msgs = [mav.MAVLink_attitude_message(k, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0),
                    mav.MAVLink_servo_output_raw_message(k, 0, 1500, 1510, 1520, 1530, 0, 0, 0, 0)]
            if k % 5 == 0:
                msgs += [mav.MAVLink_heartbeat_message(2, 3, 128, 0, 4, 3),
                         mav.MAVLink_sys_status_message(0, 0, 0, 500, 12500, 800, 50, 0, 0, 0, 0, 0, 0)]
            for msg in msgs:
                fh.write(t_us.to_bytes(8, "big") + msg.pack(link))
    return path


def _ulog_msg(kind: str, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def _ulog(path: Path, jump: float | None) -> Path:
    """A minimal ULog (spec: docs.px4.io/main/en/dev_log/ulog_file_format): header, formats, one parameter,
    sensor_combined and battery_status subscriptions and their data."""
    out = bytearray(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", 1_000_000))
    out += _ulog_msg("F", b"sensor_combined:uint64_t timestamp;float[3] gyro_rad;float[3] accelerometer_m_s2;")
    out += _ulog_msg("F", b"battery_status:uint64_t timestamp;float voltage_v;float current_a;")
    out += _ulog_msg("P", bytes([len(b"float MPC_THR_HOVER")]) + b"float MPC_THR_HOVER" + struct.pack("<f", 0.5))
    out += _ulog_msg("A", struct.pack("<BH", 0, 0) + b"sensor_combined")
    out += _ulog_msg("A", struct.pack("<BH", 0, 1) + b"battery_status")
    for k, t in enumerate(_times(50.0, jump)):
        ts = int(t * 1e6)
        out += _ulog_msg("D", struct.pack("<HQ6f", 0, ts, 0.01, 0.02, 0.03, 0.1, 0.2, -9.8))
        if k % 10 == 0:
            out += _ulog_msg("D", struct.pack("<HQff", 1, ts, 12.4, 3.0))
    path.write_bytes(bytes(out))
    return path


def test_a_signalling_nan_in_a_ulog_float_reads_as_nan_without_a_warning(tmp_path: Path) -> None:
    """Damaged bytes can form a float32 signalling NaN; widening it to float64 raises the invalid flag (numpy
    warns). The reader keeps the sample as NaN, quietly, and the rest of the signal as logged."""
    import warnings

    data = bytearray(_ulog(tmp_path / "ok.ulg", None).read_bytes())
    good = struct.pack("<f", 12.4)
    at = data.index(good)
    data[at:at + 4] = struct.pack("<I", 0x7F800001)  # the first voltage sample: a signalling NaN
    (tmp_path / "snan.ulg").write_bytes(bytes(data))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        log = read_log(tmp_path / "snan.ulg")
    volts = log.signals["battery_status.voltage_v"].values
    assert np.isnan(volts[0]) and np.all(volts[1:] == np.float32(12.4))


def _csv(path: Path, jump: float | None) -> Path:
    rows = [f"{t!r},{-9.8 + 0.01 * math.sin(t)!r},1500,12.5" for t in _times(20.0, jump).tolist()]
    path.write_text("time_s,az,pwm1,vbat\n" + "\n".join(rows) + "\n")
    return path


CSV_MAP = {"accel_body_z_m_s2": "az", "motor_1_pwm_us": "pwm1", "battery_voltage_v": "vbat"}
BUILDERS: dict[str, tuple[str, Callable[[Path, float | None], Path], dict | None]] = {
    "dataflash_bin": (".bin", _dataflash_bin, None),
    "dataflash_text": (".log", _dataflash_text, None),
    "tlog": (".tlog", _tlog, None),
    "ulog": (".ulg", _ulog, None),
    "csv": (".csv", _csv, CSV_MAP),
}


class _Bases(dict):
    def __repr__(self) -> str:  # keeps hypothesis' failure reports short
        return f"<{len(self)} base logs>"


@pytest.fixture(scope="module")
def bases(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, float | None], bytes]:
    """The undamaged bytes of every (family, jump) log, each read once as a positive control."""
    d = tmp_path_factory.mktemp("bases")
    out = _Bases()
    for family, (suffix, build, cmap) in BUILDERS.items():
        for jump in JUMPS:
            path = build(d / f"{family}_{jump}{suffix}", jump)
            log = read_log(path, channel_map=cmap)
            assert log.duration_s <= DURATION_S + 0.1, (family, jump, log.duration_s)
            if jump is None or jump > JUMP_S:
                assert log.quality.ok == (jump is None), (family, jump, log.quality.lines())
            out[(family, jump)] = path.read_bytes()
    return out


# ------------------------------------------------------------------------------------------------ damage
@functools.cache  # built once per size: a strategy built anew for every example costs Hypothesis more than it draws
def damage(size: int) -> st.SearchStrategy[list[tuple]]:
    """1..4 damage operations on a file of ``size`` bytes (positions as fractions, applied in order)."""
    frac = st.floats(0.0, 1.0)
    op = st.one_of(
        st.tuples(st.just("flip"), frac, st.integers(0, 7)),
        st.tuples(st.just("truncate"), frac),
        st.tuples(st.just("duplicate"), frac, st.integers(1, max(1, size // 4))),
        st.tuples(st.just("swap"), frac, frac, st.integers(1, max(1, size // 8))),
        st.tuples(st.just("junk"), frac, st.binary(min_size=1, max_size=64)),
        st.tuples(st.just("insert"), frac, st.binary(min_size=1, max_size=64)),
    )
    return st.lists(op, min_size=1, max_size=4)


def _apply(data: bytes, ops: list[tuple]) -> bytes:
    b = bytearray(data)
    for o in ops:
        at = min(len(b) - 1, int(o[1] * len(b))) if b else 0
        if not b:
            break
        if o[0] == "flip":
            b[at] ^= 1 << o[2]
        elif o[0] == "truncate":
            del b[at:]
        elif o[0] == "duplicate":
            b[at:at] = b[at:at + o[2]]
        elif o[0] == "swap":
            a2 = min(len(b) - 1, int(o[2] * len(b)))
            lo, hi = sorted((at, a2))
            n = min(o[3], hi - lo, len(b) - hi)
            if n > 0:
                b[lo:lo + n], b[hi:hi + n] = b[hi:hi + n], b[lo:lo + n]
        elif o[0] == "junk":
            b[at:at + len(o[2])] = o[2]
        else:
            b[at:at] = o[2]
    return bytes(b)


class _HangError(Exception):
    pass


def _alarm(signum: int, frame: Any) -> None:
    raise _HangError(f"a read took longer than {HANG_S} s")


def _check(log: FlightLog, path: Path, n_ops: int) -> None:
    """What every successfully read damaged log must satisfy."""
    bound = DURATION_S + (n_ops + 1) * JUMP_S + 1.0  # each damage can at most bridge one sub-jump pause
    assert math.isfinite(log.duration_s) and log.duration_s <= bound, (path.name, log.duration_s)
    for name, s in log.signals.items():
        assert s.t_s.shape == s.values.shape, name
        assert np.isfinite(s.t_s).all() and np.all(np.diff(s.t_s) >= 0), name
        if "." not in name and s.values.dtype.kind == "f":
            assert np.isfinite(s.values).all(), name
    q = log.quality
    assert q is not None and 0.0 <= q.damage_fraction <= 1.0
    d = json.loads(json.dumps(q.to_dict(), allow_nan=False))
    assert len(json.dumps(d)) < 20_000  # bounded, however damaged
    assert all(isinstance(line, str) and path.name in line for line in q.lines())


def _fuzz(family: str, bases: dict, tmp_path: Path, jump: float | None, ops: list[tuple]) -> None:
    suffix, _, cmap = BUILDERS[family]
    data = _apply(bases[(family, jump)], ops)
    path = tmp_path / f"damaged_{family}{suffix}"
    path.write_bytes(data)
    COUNTS[family] += 1
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, HANG_S)
    try:
        log = read_log(path, channel_map=cmap)
    except LogError as err:
        assert path.name in str(err), str(err)
        return
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    _check(log, path, len(ops))


def _family_test(family: str) -> Callable:
    def test(bases: dict, tmp_path: Path) -> None:
        ran = COUNTS[family]

        @settings(max_examples=EXAMPLES[family], **FUZZ)
        @given(data=st.data(), jump=st.sampled_from(JUMPS))
        def fuzz(data: st.DataObject, jump: float | None) -> None:
            ops = data.draw(damage(len(bases[(family, jump)])))
            _fuzz(family, bases, tmp_path, jump, ops)

        fuzz()
        ran = COUNTS[family] - ran  # examples of this test alone: the check holds in any test order
        assert ran >= MIN_SHARE * EXAMPLES[family], f"{family}: only {ran} of {EXAMPLES[family]} examples ran"

    test.__name__ = f"test_damaged_{family}_reads_or_raises_log_error"
    return test


test_damaged_dataflash_bin = _family_test("dataflash_bin")
test_damaged_dataflash_text = _family_test("dataflash_text")
test_damaged_tlog = _family_test("tlog")
test_damaged_ulog = _family_test("ulog")
test_damaged_csv = _family_test("csv")


def test_time_jumps_alone_keep_the_main_part(bases: dict, tmp_path: Path) -> None:
    """Positive control without byte damage: each jump is split off and reported, 60 % of the flight kept."""
    for family, (suffix, _, cmap) in BUILDERS.items():
        for jump in (1e6, 1e9, 3600.0):
            path = tmp_path / f"jump_{family}{suffix}"
            path.write_bytes(bases[(family, jump)])
            log = read_log(path, channel_map=cmap)
            q = log.quality
            assert log.duration_s == pytest.approx(0.6 * DURATION_S, abs=0.2), (family, jump)
            assert q.jumps and q.samples_beyond_jumps > 0 and q.damage_fraction == pytest.approx(0.4, abs=0.05)
