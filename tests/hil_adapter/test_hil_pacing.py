"""Lockstep pacing: at speed 1 simulation time keeps the wall clock's pace (fake PX4 and fake SITL over
loopback), at ``max`` it runs as fast as the autopilot answers; the pacer's schedule, the status line's
real-time factor, ``--speed`` and ``--seed`` through the session. The 30 s check of the same loops is
``bench/hil_realtime.py``."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from hil_adapter.core import MAX_LAG_S, SimClockPacer, Stats
from hil_adapter.session import HilSetupError, parse_speed, serve
from tests.fakes.hil import DT, LockstepPx4Client, free_tcp_port, json_pace, px4_pace

#: wall-clock pacing: `make test` runs these on their own, after the parallel run, so no other test shares the cores
pytestmark = pytest.mark.realtime

#: how long each paced test runs [s]; the 30 s runs are bench/hil_realtime.py
PACED_S = 3.0


@pytest.mark.parametrize("run", [px4_pace, json_pace], ids=["px4", "json"])
def test_speed_1_keeps_simulation_time_within_2_percent_of_wall_time(quadrotor_fmu: Path, run) -> None:
    sim, wall, stats = run(quadrotor_fmu, 1.0, PACED_S)
    print(f"{run.__name__}: {sim:.3f} s simulated in {wall:.3f} s of wall time ({sim / wall:.4f}x)")
    assert wall > 0.8 * PACED_S
    assert sim / wall == pytest.approx(1.0, abs=0.02)
    assert stats.real_time_factor == pytest.approx(1.0, abs=0.02)  # what the summary reports


@pytest.mark.parametrize("run", [px4_pace, json_pace], ids=["px4", "json"])
def test_speed_max_runs_as_fast_as_the_autopilot_answers(quadrotor_fmu: Path, run) -> None:
    """Unpaced, the same loops run several times faster than real time (8-10x with real PX4 SITL): speed max
    does not wait; speed 2 holds twice real time."""
    sim, wall, _ = run(quadrotor_fmu, None, 1.5)
    print(f"{run.__name__} max: {sim / wall:.2f}x real time")
    assert sim / wall > 2.5
    sim2, wall2, _ = run(quadrotor_fmu, 2.0, 1.5)
    assert sim2 / wall2 == pytest.approx(2.0, rel=0.03)


def test_pacer_keeps_schedule_and_restarts_it_instead_of_bursting() -> None:
    stats = Stats()
    pacer = SimClockPacer(1.0, stats)
    t0 = time.perf_counter()
    for k in range(26):  # 25 steps of 4 ms: 0.1 s
        pacer.wait(k * DT)
    assert time.perf_counter() - t0 == pytest.approx(0.1, abs=0.01)
    k = 26
    for _ in range(int(MAX_LAG_S / (0.1 - DT)) + 1):  # a slow autopilot, 0.1 s per 4 ms step, till beyond the bound
        time.sleep(0.1)
        pacer.wait(k * DT)
        k += 1
    assert stats.overruns == 1
    t1 = time.perf_counter()
    for j in range(k, k + 26):  # the schedule restarted at the overrun: no burst of unpaced steps to catch up
        pacer.wait(j * DT)
    assert time.perf_counter() - t1 == pytest.approx(0.1, abs=0.01)
    time.sleep(2 * MAX_LAG_S)  # a pause (the autopilot stopped sending): a new schedule, not an overrun
    t2 = time.perf_counter()
    for j in range(k + 26, k + 52):
        pacer.wait(j * DT)
    assert time.perf_counter() - t2 == pytest.approx(0.1, abs=0.01)
    assert stats.overruns == 1
    with pytest.raises(ValueError, match=r"0.01..1000 or 'max'"):
        SimClockPacer(0.0, stats)


def test_status_line_shows_the_real_time_factor() -> None:
    stats = Stats()
    for _ in range(50):
        stats.step(dt_s=DT)
        time.sleep(DT / 2)  # twice real time
    line = stats.line()
    rtf = float(line.split("rtf=")[1].split("x")[0])
    assert rtf == pytest.approx(2.0, rel=0.25)  # sleep granularity on a loaded machine
    assert stats.summary()["real_time_factor"] == pytest.approx(rtf, rel=0.25)


def test_parse_speed() -> None:
    assert parse_speed("max") == "max" and parse_speed("2") == 2.0 and parse_speed("0.5") == 0.5
    for bad in ("0", "-1", "fast", "nan", "1e9"):
        with pytest.raises(ValueError, match=r"--speed .*allowed 0.01..1000 or max"):
            parse_speed(bad)


def _px4_session(fmu: Path, **kwargs) -> dict:
    """A short lockstep PX4 session through ``serve`` with a fake PX4; its summary."""
    port = free_tcp_port()
    client = LockstepPx4Client(port, max_s=5.0)
    th = threading.Thread(target=client.run)
    th.start()
    result = serve(fmu, "px4", port=port, duration_s=0.6, **kwargs)
    th.join(timeout=10)
    return result.summary


def test_session_prints_speed_and_a_fresh_seed_unless_given(quadrotor_fmu: Path) -> None:
    a, b = _px4_session(quadrotor_fmu), _px4_session(quadrotor_fmu)
    assert a["speed"] == 1.0 and a["seed"] != b["seed"]  # fresh seeds: runs differ unless asked to repeat
    c = _px4_session(quadrotor_fmu, seed=a["seed"], speed="max")
    assert c["seed"] == a["seed"] and c["speed"] == "max"
    assert c["real_time_factor"] > 1.5 * a["real_time_factor"]


def test_options_that_would_do_nothing_are_errors(quadrotor_fmu: Path, tmp_path: Path) -> None:
    cfg = tmp_path / "bench.toml"
    cfg.write_text("[timing]\nmode = \"realtime\"\n")
    with pytest.raises(HilSetupError, match="only lockstep runs"):
        serve(quadrotor_fmu, "px4", cfg, speed=2.0, port=free_tcp_port())
    with pytest.raises(HilSetupError, match="--seed: ardupilot-json adds sensor noise only with a"):
        serve(quadrotor_fmu, "ardupilot-json", seed=3, port=0)
    with pytest.raises(HilSetupError, match="--seed: the nmea interface sends the FMU's GPS truth"):
        serve(quadrotor_fmu, "nmea", seed=3)
    cfg.write_text("[timing]\nspeed = 0\n")
    with pytest.raises(HilSetupError, match=r"timing\.speed.*= 0.*>= 0.01"):
        serve(quadrotor_fmu, "px4", cfg)


def test_same_seed_same_noise_through_the_config(tmp_path: Path) -> None:
    from hil_adapter.config import HilConfig, sensor_suite

    truth = {"accel_body_x_m_s2": 0.0, "accel_body_y_m_s2": 0.0, "accel_body_z_m_s2": -9.8,
             "rate_body_x_rad_s": 0.0, "rate_body_y_rad_s": 0.0, "rate_body_z_rad_s": 0.0,
             "quat_w": 1.0, "quat_x": 0.0, "quat_y": 0.0, "quat_z": 0.0, "lat_deg": 47.4, "lon_deg": 8.5,
             "height_m": 490.0, "vel_north_m_s": 0.0, "vel_east_m_s": 0.0, "vel_down_m_s": 0.0}

    def accel(suite) -> np.ndarray:
        return np.array([suite.sample(k * DT, truth).accel_body_m_s2 for k in range(1, 20)])

    cfg = HilConfig(sensors={"seed": 5})
    assert np.array_equal(accel(sensor_suite(cfg)), accel(sensor_suite(HilConfig(), seed=5)))
    assert sensor_suite(cfg, seed=6).seed == 6  # --seed overrides [sensors] seed
    assert not np.array_equal(accel(sensor_suite(HilConfig())), accel(sensor_suite(HilConfig())))
    with pytest.raises(ValueError, match=r"allowed 0\.\.2"):
        sensor_suite(HilConfig(), seed=-1)
