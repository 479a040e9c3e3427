"""HIL lockstep loop over loopback: steps per second and round-trip latency p50/p99 of the PX4 (TCP, MAVLink)
and ArduPilot JSON (UDP) interfaces with the quadrotor FMU, next to the FMU's bare step cost measured in the
same run. The adapter runs in its own process (as it would beside a real autopilot); a minimal fake
autopilot in this process measures each round trip from sending its actuator message to receiving the next
sensor message; the adapter reports its busy time per step (autopilot input in -> our reply out).

Targets (issue 6): >= 1000 lockstep steps/s, p99 round trip < 1 ms, adapter overhead per step (busy time
minus the FMU step) below the FMU's own step cost. The FMU step is timed twice: inside the loop (same cache
and scheduling conditions as the adapter's own work) and bare, in a tight loop with warm caches.

Run: ``.venv/bin/python bench/hil_loop.py [--steps 5000]``.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import socket
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pymavlink.dialects.v20 import common as mavlink2

from build_fmus import build
from hil_adapter.packets import ServoPacket
from uavfmu.fmu_host import FmuHost


def serve(kind: str, fmu: str, port_q: mp.Queue, steps: int, busy_q: mp.Queue) -> None:
    _pin(0)
    from hil_adapter.ardupilot_json import ArduPilotJsonServer, UdpTransport
    from hil_adapter.core import Plant
    from hil_adapter.px4 import Px4Server
    from hil_adapter.sensors import SensorSuite

    plant = Plant(fmu)
    if kind == "px4":
        srv = Px4Server(plant, SensorSuite(seed=1), port=0, dt_s=0.004)
        port_q.put(srv.address[1])
        stats = srv.serve(max_steps=steps, accept_timeout_s=1.0)
    else:
        tr = UdpTransport("127.0.0.1", 0)
        port_q.put(tr.address[1])
        stats = ArduPilotJsonServer(plant, tr).serve(max_frames=steps, idle_timeout_s=1.0)
    busy_q.put((float(np.mean(stats.busy)), float(np.mean(plant.step_times))))
    plant.close()


def _pin(cpu: int) -> None:
    """Keep a process on one core (adapter and fake autopilot on different cores, as on a bench PC)."""
    if hasattr(os, "sched_setaffinity") and (os.cpu_count() or 1) > 1:
        os.sched_setaffinity(0, {cpu % (os.cpu_count() or 1)})


def bare_step_us(fmu: Path, n: int) -> float:
    """One FMU step as any FMPy importer does it: set the inputs, doStep, get the outputs an interface sends."""
    from hil_adapter.core import OPTIONAL_OUTPUTS, STATE_OUTPUTS

    with FmuHost(fmu) as host:
        host.start()
        outputs = [n for n in STATE_OUTPUTS + OPTIONAL_OUTPUTS if n in host.variables]
        inputs = {f"pwm_{k}_us": 1000.0 for k in range(1, 5)}
        t0 = time.perf_counter()
        for k in range(n):
            host.step(k * 0.004, 0.004, inputs)
            host.get(outputs)
        return 1e6 * (time.perf_counter() - t0) / n


def px4_client(port: int, steps: int) -> np.ndarray:
    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    rtt, pending, sent_at = [], [], None
    controls = [0.0] * 16
    armed = mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
    while len(rtt) < steps - 1:
        got = False
        while not got:
            while pending:
                if pending.pop(0).get_type() == "HIL_STATE_QUATERNION":
                    got = True
                    break
            if not got:
                pending += mav.parse_buffer(sock.recv(65536)) or []
        if sent_at is not None:
            rtt.append(time.perf_counter() - sent_at)
        sent_at = time.perf_counter()
        sock.sendall(mav.hil_actuator_controls_encode(0, controls, armed, 1).pack(mav))
    sock.close()
    return np.array(rtt)


def json_client(port: int, steps: int) -> np.ndarray:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.settimeout(5)
    rtt = []
    for k in range(1, steps + 1):
        t0 = time.perf_counter()
        sock.sendto(ServoPacket(250, k, (1000,) * 16).pack(), ("127.0.0.1", port))
        sock.recvfrom(65536)
        rtt.append(time.perf_counter() - t0)
    sock.close()
    return np.array(rtt)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=5000)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        fmu = build(None, Path(tmp), ["quadrotor"])[0]
        _pin(1)
        step_us = bare_step_us(fmu, args.steps)
        print(f"bare FMU step (setReal + doStep + getReal of the sent outputs, FMPy FMU2Slave): {step_us:.1f} us")
        for kind, client in (("px4", px4_client), ("ardupilot-json", json_client)):
            q: mp.Queue = mp.Queue()
            busy_q: mp.Queue = mp.Queue()
            proc = mp.Process(target=serve, args=(kind, str(fmu), q, args.steps + 1, busy_q), daemon=True)
            proc.start()
            port = q.get(timeout=60)
            time.sleep(0.2)
            t0 = time.perf_counter()
            rtt = client(port, args.steps)
            wall = time.perf_counter() - t0
            busy_s, fmu_s = busy_q.get(timeout=30)
            busy_us, fmu_us = 1e6 * busy_s, 1e6 * fmu_s
            proc.join(timeout=30)
            rate = len(rtt) / wall
            p50, p99 = np.percentile(rtt, [50, 99]) * 1e6
            overhead = busy_us - fmu_us
            print(f"{kind:<15} {rate:6.0f} steps/s (target >= 1000); round trip p50 {p50:4.0f} us, p99 {p99:4.0f} us "
                  f"(target < 1000); adapter busy {busy_us:4.0f} us/step, of which the FMU step {fmu_us:4.0f} us; "
                  f"overhead {overhead:4.0f} us = {overhead / fmu_us:.2f}x the FMU step in the loop, "
                  f"{overhead / step_us:.2f}x the bare one (target < 1x)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
