"""``hil_adapter.session.serve`` (what ``uavfmu hil`` runs): serve a fake SITL, record, summarise; bad configs
are ``HilSetupError``/``ConfigError`` naming file, field, value and range, never a traceback."""

from __future__ import annotations

import itertools
import socket
import threading
from pathlib import Path

import pytest

from fmu_models.config import ConfigError
from hil_adapter.config import load_hil_config
from hil_adapter.packets import ServoPacket, parse_json_state
from hil_adapter.session import HilResult, HilSetupError, serve
from identification.logs.readers import read_log


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_json_session_records_and_summarises(quadrotor_fmu: Path, tmp_path: Path) -> None:
    port = free_udp_port()
    cfg = tmp_path / "bench.toml"
    cfg.write_text("[watchdog]\ntimeout_s = 1.0\nmode = \"hold\"\n[sensors]\nseed = 3\n")
    record = tmp_path / "rec.csv"
    out: list[HilResult] = []
    stop = threading.Event()
    th = threading.Thread(target=lambda: out.append(serve(quadrotor_fmu, "ardupilot-json", cfg, port=port,
                                                          record=record, duration_s=20, stop=stop)))
    th.start()
    sitl = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sitl.settimeout(0.5)
    answered, times = 0, []
    for k in range(1, 2000):
        if answered >= 200 or not th.is_alive():
            break
        sitl.sendto(ServoPacket(400, k, (1000,) * 16).pack(), ("127.0.0.1", port))
        try:
            times.append(parse_json_state(sitl.recvfrom(65536)[0])["timestamp"])
            answered += 1
        except TimeoutError:
            continue  # the server may still be starting
    sitl.close()
    stop.set()
    th.join(timeout=15)
    (result,) = out
    assert answered >= 200 and times[0] > 0 and all(b > a for a, b in itertools.pairwise(times))
    assert result.stopped_by == "stopped" and result.summary["steps"] == answered
    assert result.summary["step_rate_hz"] > 0 and result.summary["stepping_s"] > 0
    assert result.record_rows == answered and any(line.startswith("record:") for line in result.lines())
    log = read_log(record)
    assert len(log.signal("altitude_m").t_s) == answered
    assert log.signal("servo_1_pwm_us").values[-1] == 1000.0
    assert log.signal("out_of_band").values.max() == 0.0  # 1000 us is below idle: not out of band


@pytest.mark.parametrize(("text", "needle"), [
    ("[timing]\nmode = \"warp\"\n[network]\nhots = \"x\"\n", "timing.mode = 'warp'"),
    ("[px4]\nrc_channels = \"abc\"\n", "px4.rc_channels = 'abc'"),
    ("[timing]\nrate_hz = true\n", "timing.rate_hz = True"),
    ("[timing]\nrate_hz = 1e6\n", "<= 10000"),
    ("[timing]\nbusy_poll_us = -5\n", "timing.busy_poll_us = -5"),
    ("[watchdog]\ntimeout_s = \"fast\"\n", "watchdog.timeout_s = 'fast'"),
    ("[px4]\nrc_channels = [1500, 9999]\n", "px4.rc_channels.1 = 9999"),
    ("[px4]\nwing_controls = {\"17\" = 0}\n", "px4.wing_controls.17"),
    ("[start]\ninit_pos_down_m = nan\n", "start.init_pos_down_m = nan"),
    ("[sensors.gyro]\nnoise_std = -1\n", "gyro.noise_std = -1"),
    ("[sensors]\nseed = \"x\"\n", "sensors.seed = 'x'"),
    ("[network]\nport = 70000\n", "network.port = 70000"),
    ("[record]\npath = 3\n", "record.path = 3"),
])
def test_bad_configs_name_file_field_and_value(tmp_path: Path, text: str, needle: str) -> None:
    cfg = tmp_path / "bench.toml"
    cfg.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_hil_config(cfg)
    assert str(cfg) in str(err.value) and needle in str(err.value), str(err.value)


def test_setup_errors_are_setup_errors(quadrotor_fmu: Path, tmp_path: Path) -> None:
    cfg = tmp_path / "bench.toml"
    cfg.write_text("[timing]\nmode = \"warp\"\n")
    with pytest.raises(HilSetupError, match=r"timing\.mode"):
        serve(quadrotor_fmu, "px4", cfg)
    with pytest.raises(HilSetupError, match="not found"):
        serve(tmp_path / "none.fmu", "nmea")
    with pytest.raises(HilSetupError, match="duration_s"):
        serve(quadrotor_fmu, "px4", duration_s=-1)
    with pytest.raises(HilSetupError, match=r"\[nmea\] section"):
        serve(quadrotor_fmu, "nmea", duration_s=1)


@pytest.mark.realtime  # paced by the wall clock: run alone
def test_nmea_interface_streams_gps_sentences(quadrotor_fmu: Path, tmp_path: Path) -> None:
    cfg = tmp_path / "bench.toml"
    cfg.write_text("[nmea]\nport = \"loop://\"\nrate_hz = 5\n[timing]\nrate_hz = 100\n")
    result = serve(quadrotor_fmu, "nmea", cfg, duration_s=1.5)
    assert result.stopped_by == "duration"
    assert 100 <= result.summary["steps"] <= 200  # 1.5 s of real time at 100 Hz
    assert result.summary["step_rate_hz"] == pytest.approx(100, rel=0.2)  # over the stepping time
