"""``uavfmu hil``: serve a fake SITL from the command line, record, summarise; bad configs exit 2."""

from __future__ import annotations

import socket
import threading
from pathlib import Path

from hil_adapter.packets import ServoPacket, parse_json_state
from identification.readers import read_log
from uavfmu.cli import main


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_json_interface_from_the_cli_records_and_summarises(quadrotor_fmu: Path, tmp_path: Path, capsys) -> None:
    port = free_udp_port()
    cfg = tmp_path / "bench.toml"
    cfg.write_text("[watchdog]\ntimeout_s = 1.0\nmode = \"hold\"\n[sensors]\nseed = 3\n")
    record = tmp_path / "rec.csv"
    rc: list[int] = []
    th = threading.Thread(target=lambda: rc.append(main([
        "hil", str(quadrotor_fmu), "--interface", "ardupilot-json", "--port", str(port), "--config", str(cfg),
        "--record", str(record), "--duration-s", "3", "--quiet"])))
    th.start()
    sitl = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sitl.settimeout(0.5)
    answered = 0
    for k in range(1, 2000):
        if answered >= 200 or not th.is_alive():
            break
        sitl.sendto(ServoPacket(400, k, (1000,) * 16).pack(), ("127.0.0.1", port))
        try:
            state = parse_json_state(sitl.recvfrom(65536)[0])
            answered += 1
        except TimeoutError:
            continue  # the server may still be starting
    sitl.close()
    th.join(timeout=15)
    assert rc == [0]
    assert answered >= 200 and state["timestamp"] > 0
    out = capsys.readouterr().out
    assert "summary: steps" in out and "record:" in out
    log = read_log(record)
    assert len(log.signal("altitude_m").t_s) >= 200
    assert log.signal("servo_1_pwm_us").values[-1] == 1000.0


def test_bad_config_exits_2_with_the_key_named(quadrotor_fmu: Path, tmp_path: Path, capsys) -> None:
    cfg = tmp_path / "bench.toml"
    cfg.write_text("[timing]\nmode = \"warp\"\n[network]\nhots = \"x\"\n[sensors.gyro]\nnoise_std = -1\n")
    assert main(["hil", str(quadrotor_fmu), "--interface", "px4", "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert "timing.mode = 'warp'" in err and "network.hots" in err
    cfg.write_text("[sensors.gyro]\nnoise_std = -1\n")
    assert main(["hil", str(quadrotor_fmu), "--interface", "px4", "--config", str(cfg), "--port", "0"]) == 2
    assert "noise_std" in capsys.readouterr().err
    assert main(["hil", str(tmp_path / "none.fmu"), "--interface", "nmea"]) == 2
    assert "not found" in capsys.readouterr().err
    cfg.write_text("[timing]\nbusy_poll_us = -5\n")
    assert main(["hil", str(quadrotor_fmu), "--interface", "ardupilot-json", "--config", str(cfg)]) == 2
    assert "timing.busy_poll_us = -5; allowed: 0..100000" in capsys.readouterr().err


def test_nmea_interface_streams_gps_sentences(quadrotor_fmu: Path, tmp_path: Path, capsys) -> None:
    cfg = tmp_path / "bench.toml"
    cfg.write_text("[nmea]\nport = \"loop://\"\nrate_hz = 5\n[timing]\nrate_hz = 100\n")
    assert main(["hil", str(quadrotor_fmu), "--interface", "nmea", "--config", str(cfg), "--duration-s", "1.5",
                 "--quiet"]) == 0
    out = capsys.readouterr().out
    steps = int(out.split("summary: steps ")[1].split(",")[0])
    assert 100 <= steps <= 200  # 1.5 s of real time at 100 Hz
