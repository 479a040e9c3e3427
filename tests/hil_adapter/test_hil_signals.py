"""Clean stops and honest restarts: SIGINT/SIGTERM end a running lockstep session between
steps with a summary and exit 0; a restart while PX4 is connected never sends time backwards."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from fmu_models.fmi.host import FmuRunError
from hil_adapter.core import Plant, Watchdog
from hil_adapter.px4 import Px4Server
from hil_adapter.sensors import SensorConfig, SensorSuite
from tests.fakes.hil import LockstepPx4Client, free_tcp_port, serving

REPO = Path(__file__).resolve().parents[2]
SESSIONS = 50


def test_sigint_at_random_moments_50_sessions(quadrotor_fmu: Path) -> None:
    """50 lockstep sessions with a fake PX4, each interrupted by SIGINT at a random moment (in a separate
    process: a segfault shows as a negative return code)."""
    code = ("import sys; from tests.fakes.hil import sigint_sessions; "
            f"sys.exit(sigint_sessions({str(quadrotor_fmu)!r}, {SESSIONS}, 17))")
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=300)
    print(proc.stdout.splitlines()[-1] if proc.stdout else proc.stderr[-2000:])
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert f"sigint sessions: {SESSIONS}, failed: 0" in proc.stdout
    assert proc.stdout.count("stopped_by=signal SIGINT") == SESSIONS


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_cli_stops_on_signal_with_a_summary_and_exit_0(quadrotor_fmu: Path, tmp_path: Path, sig: int) -> None:
    port = free_tcp_port()
    proc = subprocess.Popen([sys.executable, "-m", "uavfmu.cli", "hil", str(quadrotor_fmu), "--interface", "px4",
                             "--port", str(port), "--quiet", "--record", str(tmp_path / "rec.csv")], cwd=REPO,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    client = LockstepPx4Client(port, controls=0.5, max_s=60)
    th = threading.Thread(target=client.run)
    th.start()
    try:
        assert client.connected.wait(60), proc.stderr
        time.sleep(0.5)
        os.kill(proc.pid, sig)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
        th.join(timeout=10)
    assert proc.returncode == 0, err
    assert f"summary (signal {signal.Signals(sig).name}): steps" in out and "record:" in out
    assert client.steps > 10 and client.backwards == 0


def test_fmu_failure_while_px4_is_connected_keeps_time_monotonic(quadrotor_fmu: Path) -> None:
    """The 100th step fails: the FMU is freed and instantiated again (never reset), PX4's clock goes on."""
    plant = Plant(quadrotor_fmu)
    port = free_tcp_port()
    srv = Px4Server(plant, SensorSuite(SensorConfig.noise_free()), port=port, dt_s=0.004,
                    watchdog=Watchdog(timeout_s=2.0))
    real_step = plant.host.step
    calls = [0]

    def flaky(t_s: float, dt_s: float, inputs: dict | None = None) -> None:
        calls[0] += 1
        if calls[0] == 100:
            raise FmuRunError("injected fatal")
        real_step(t_s, dt_s, inputs)

    plant.host.step = flaky  # type: ignore[method-assign]
    client = LockstepPx4Client(port, controls=0.55, max_s=5)
    try:
        with serving(srv, max_steps=250):
            client.run()
    finally:
        srv.close()
        plant.close()
    assert plant.fmu_errors == 1 and plant.reinstantiations == 1
    assert client.steps >= 250 and client.backwards == 0
    assert client.times_us[0] > 0
