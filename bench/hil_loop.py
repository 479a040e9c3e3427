"""HIL lockstep loop over loopback: steps per second and round-trip latency p50/p99 of the PX4 (TCP, MAVLink)
and ArduPilot JSON (UDP) interfaces with the quadrotor FMU, next to the FMU's bare step cost measured in the
same run. The adapter runs in its own process (as it would beside a real autopilot); a minimal fake
autopilot in this process measures each round trip from sending its actuator message to receiving the next
sensor message; the adapter reports its busy time per step (autopilot input received -> our reply sent).

The target: the adapter's own work per step - packet decode, input mapping, sensor models, packet
encode - at or below the FMU step (setReal + doStep + getReal through FMPy). It is measured in one process on
the servers' own code paths, each step timing the adapter's work and the FMU step back to back (so a machine
loaded by others slows both alike); the ratio of the medians is taken within each run, the median over runs
is printed, and the script exits 1 when it is above 1 for PX4 or JSON. PX4: ``Px4Server._absorb`` (decode and
controls -> PWM), ``Plant.apply`` (PWM mapping), ``_send_step`` (sensor models and HIL_SENSOR,
HIL_STATE_QUATERNION, HIL_GPS at 5 Hz, HEARTBEAT at 1 Hz framed) into a null socket. JSON:
``ArduPilotJsonServer.handle`` minus its FMU step (servo packet decode and checks, mapping, JSON reply; no
sensor models: the session adds them only when ``[sensors]`` is configured, SITL has its own). The kernel's
send is not the adapter's work and is left out here.

Beside it, for context (not the target): the lockstep loop over loopback with the adapter in its own process -
steps per second, round trip p50/p99 and the adapter's busy time per step - and a null server per interface
(same socket, same busy poll, the same reply bytes sent back with no work) that shows the transport's own cost.

Run: ``.venv/bin/python bench/hil_loop.py [--steps 5000] [--repeat 3] [--busy-poll-us 500] [--no-loop]``.
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
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pymavlink.dialects.v20 import common as mavlink2

from build_fmus import build
from fmu_models.fmi.host import FmuHost
from hil_adapter.core import BUSY_POLL_S
from hil_adapter.packets import ServoPacket


def serve(kind: str, fmu: str, port_q: mp.Queue, steps: int, busy_q: mp.Queue, busy_poll_s: float) -> None:
    _pin(0)
    from hil_adapter.ardupilot_json import ArduPilotJsonServer, UdpTransport
    from hil_adapter.core import Plant
    from hil_adapter.px4 import Px4Server
    from hil_adapter.sensors import SensorSuite

    plant = Plant(fmu)
    if kind == "px4":
        srv = Px4Server(plant, SensorSuite(seed=1), port=0, dt_s=0.004, busy_poll_s=busy_poll_s)
        port_q.put(srv.address[1])
        stats = srv.serve(max_steps=steps, accept_timeout_s=1.0)
    else:
        tr = UdpTransport("127.0.0.1", 0, busy_poll_s=busy_poll_s)
        port_q.put(tr.address[1])
        stats = ArduPilotJsonServer(plant, tr).serve(max_frames=steps, idle_timeout_s=1.0)
    busy_q.put((float(np.median(stats.busy)), float(np.median(plant.step_times))))
    plant.close()


def serve_null(kind: str, reply: bytes, work_s: float, port_q: mp.Queue, steps: int, busy_q: mp.Queue,
               busy_poll_s: float) -> None:
    """The transport alone: receive as the adapter does, wait ``work_s`` (the adapter's busy time, so that the
    autopilot sleeps as long as with the adapter: waking it is most of the cost of ``send``), send back
    ``reply`` (a real reply's bytes); reports the median time of the send."""
    _pin(0)
    from hil_adapter.ardupilot_json import UdpTransport
    from hil_adapter.core import SocketSpinner
    from hil_adapter.px4 import tcp_listener

    busy = []
    if kind == "px4":
        server = tcp_listener("127.0.0.1", 0)
        port_q.put(server.getsockname()[1])
        conn, _ = server.accept()
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn.settimeout(1.0)
        conn.sendall(reply)
        spinner = SocketSpinner(conn, busy_poll_s)
        for _ in range(steps - 1):
            spinner.wait()
            if not conn.recv(65536):
                break
            _spin(work_s)
            t0 = time.perf_counter()
            conn.sendall(reply)
            busy.append(time.perf_counter() - t0)
        conn.close()
        server.close()
    else:
        tr = UdpTransport("127.0.0.1", 0, busy_poll_s=busy_poll_s)
        port_q.put(tr.address[1])
        for _ in range(steps):
            got = tr.recv(1.0)
            if got is None:
                break
            _spin(work_s)
            t0 = time.perf_counter()
            tr.send(reply, got[1])
            busy.append(time.perf_counter() - t0)
        tr.close()
    busy_q.put((float(np.median(busy)), 0.0))


def _spin(duration_s: float) -> None:
    end = time.perf_counter() + duration_s
    while time.perf_counter() < end:
        pass


def sample_replies(fmu: Path) -> dict[str, bytes]:
    """One step's reply bytes of each interface (for the null servers)."""
    from pymavlink.dialects.v20 import common as mavlink2

    from hil_adapter.ardupilot_json import ArduPilotJsonServer
    from hil_adapter.core import Plant
    from hil_adapter.px4 import HilMessages
    from hil_adapter.sensors import SensorSuite

    plant = Plant(fmu)
    try:
        plant.advance(0.004)
        msgs = HilMessages(mavlink2.MAVLink(None, 1, 51), plant.vehicle)
        frame = SensorSuite(seed=1).sample(plant.t_s, plant.state)
        px4 = msgs.sensor(4000, frame) + msgs.state(4000, plant.state)
        return {"px4": px4, "ardupilot-json": ArduPilotJsonServer(plant, None).reply()}
    finally:
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


def run_pair(target: Any, args: tuple, client: Any, steps: int) -> tuple[np.ndarray, float, float, float]:
    """Start a server process, drive it with ``client``: round trips [s], wall time [s], its busy and FMU
    medians [s]."""
    q: mp.Queue = mp.Queue()
    busy_q: mp.Queue = mp.Queue()
    proc = mp.Process(target=target, args=(*args[:-1], q, steps + 1, busy_q, args[-1]), daemon=True)
    proc.start()
    port = q.get(timeout=60)
    time.sleep(0.2)
    t0 = time.perf_counter()
    rtt = client(port, steps)
    wall = time.perf_counter() - t0
    busy_s, fmu_s = busy_q.get(timeout=30)
    proc.join(timeout=30)
    return rtt, wall, busy_s, fmu_s


def one_run(fmu: Path, replies: dict[str, bytes], steps: int, poll_s: float) -> dict[str, dict[str, float]]:
    """Every figure of one run [us, steps/s], per interface."""
    step_us = bare_step_us(fmu, steps)
    out = {}
    for kind, client in (("px4", px4_client), ("ardupilot-json", json_client)):
        rtt, wall, busy_s, fmu_s = run_pair(serve, (kind, str(fmu), poll_s), client, steps)
        _, _, send_s, _ = run_pair(serve_null, (kind, replies[kind], busy_s, poll_s), client, steps)
        p50, p99 = np.percentile(rtt, [50, 99]) * 1e6
        out[kind] = {"bare_us": step_us, "rate": len(rtt) / wall, "p50_us": p50, "p99_us": p99,
                     "busy_us": 1e6 * busy_s, "fmu_us": 1e6 * fmu_s, "send_us": 1e6 * send_s}
        r = out[kind]
        print(f"  {kind:<15} {r['rate']:5.0f} steps/s, p50 {p50:4.0f} us, p99 {p99:4.0f} us, busy {r['busy_us']:4.0f}"
              f" us, FMU step {r['fmu_us']:3.0f} us (bare {step_us:3.0f}), send alone {r['send_us']:3.0f} us",
              flush=True)
    return out


class _NoListener:
    """A listener that never accepts: the server's per-step code is driven directly."""

    def accept(self) -> tuple[socket.socket, Any]:
        raise TimeoutError

    def settimeout(self, timeout: float | None) -> None:
        pass

    def getsockname(self) -> str:
        return "none"

    def close(self) -> None:
        pass


class _NullConn:
    """Takes the reply bytes and drops them (the kernel's send is transport, not the adapter's work)."""

    def sendall(self, data: bytes) -> None:
        pass


def adapter_work(kind: str, fmu: Path, steps: int) -> tuple[float, float, float]:
    """Medians [us] of the adapter's own work and of the FMU step, timed back to back on every step, and the
    ratio of their 1 %-trimmed means."""
    from hil_adapter.ardupilot_json import ArduPilotJsonServer
    from hil_adapter.core import Plant
    from hil_adapter.px4 import Px4Server
    from hil_adapter.sensors import SensorSuite

    plant = Plant(fmu)
    own, fmu_t = np.empty(steps), np.empty(steps)
    clock = time.perf_counter
    try:
        if kind == "px4":
            srv = Px4Server(plant, SensorSuite(seed=1), listener=_NoListener(), dt_s=0.004)
            mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
            armed = mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
            msgs = [mav.hil_actuator_controls_encode(k, [0.5 + 1e-4 * (k % 7)] * 16, armed, 1).pack(mav)
                    for k in range(steps)]
            conn = _NullConn()
            for k in range(steps):
                t0 = clock()
                srv._absorb(msgs[k])
                plant.apply(srv.pwm)
                t1 = clock()
                plant.advance(0.004)
                t2 = clock()
                srv._send_step(conn)  # type: ignore[arg-type]
                t3 = clock()
                own[k], fmu_t[k] = (t1 - t0) + (t3 - t2), t2 - t1
        else:
            srv = ArduPilotJsonServer(plant, None)  # type: ignore[arg-type]
            packets = [ServoPacket(250, k + 1, tuple(1000 + (k % 7) for _ in range(16))).pack() for k in range(steps)]
            for k in range(steps):
                t0 = clock()
                srv.handle(packets[k])
                total = clock() - t0
                fmu_t[k] = plant.step_times[-1]
                own[k] = total - fmu_t[k]
    finally:
        plant.close()
    return 1e6 * float(np.median(own)), 1e6 * float(np.median(fmu_t)), _trimmed_mean_ratio(own, fmu_t)


def _trimmed_mean_ratio(own: np.ndarray, fmu_t: np.ndarray, cut: float = 0.01) -> float:
    """Ratio of the means with the slowest 1 % of steps of each left out (preemption by other processes); it
    keeps the periodic work (GPS, barometer, magnetometer, noise blocks) that the medians pass over."""
    def trimmed(x: np.ndarray) -> float:
        return float(np.mean(np.sort(x)[:max(1, int(len(x) * (1 - cut)))]))

    return trimmed(own) / trimmed(fmu_t)


def reconnect_ms(fmu: Path, cycles: int = 20, steps: int = 20) -> np.ndarray:
    """PX4 leaves and comes back ``cycles`` times: wall time [ms] from the client's connect() to the first
    HIL_SENSOR on the new connection (the FMU restarts in between; the target is < 100 ms, well inside a ground
    station's link timeout)."""
    import threading

    from hil_adapter.core import Plant, Watchdog
    from hil_adapter.px4 import Px4Server
    from hil_adapter.sensors import SensorConfig, SensorSuite

    plant = Plant(fmu)
    srv = Px4Server(plant, SensorSuite(SensorConfig.noise_free()), port=0, watchdog=Watchdog(timeout_s=2.0))
    stop = threading.Event()
    th = threading.Thread(target=srv.serve, kwargs={"stop": stop}, daemon=True)
    th.start()
    waits = []
    try:
        for _ in range(cycles):
            mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
            t0 = time.perf_counter()
            sock = socket.create_connection(srv.address, timeout=5.0)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            first, n = None, 0
            while n < steps:
                for m in mav.parse_buffer(sock.recv(65536)) or []:
                    if m.get_type() == "HIL_SENSOR":
                        first = first or time.perf_counter()
                        n += 1
                        sock.sendall(mav.hil_actuator_controls_encode(m.time_usec, [0.0] * 16, 0, 1).pack(mav))
            waits.append(1e3 * (first - t0))
            sock.close()
    finally:
        stop.set()
        th.join(timeout=5)
        srv.close()
        plant.close()
    return np.array(waits)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--repeat", type=int, default=3, help="runs; the summary is their median")
    parser.add_argument("--busy-poll-us", type=float, default=BUSY_POLL_S * 1e6,
                        help="the adapter's busy poll before blocking receives (0: off)")
    parser.add_argument("--no-loop", action="store_true", help="only the adapter-work target, no loopback loop")
    args = parser.parse_args()
    if not (100 <= args.steps <= 1_000_000 and 1 <= args.repeat <= 100):
        parser.error("--steps 100..1000000, --repeat 1..100")
    poll_s = args.busy_poll_us * 1e-6
    with tempfile.TemporaryDirectory() as tmp:
        fmu = build(None, Path(tmp), ["quadrotor"])[0]
        _pin(1)
        work = {kind: [adapter_work(kind, fmu, args.steps) for _ in range(args.repeat)]
                for kind in ("px4", "ardupilot-json")}
        if not args.no_loop:
            _loop_context(fmu, args, poll_s)
    print(f"adapter work per step vs the FMU step, same process, timed back to back ({args.repeat} runs of "
          f"{args.steps} steps; ratio of medians within each run, median over runs):")
    missed = []
    for kind, runs in work.items():
        ratios = [own / step for own, step, _ in runs]
        ratio = float(np.median(ratios))
        own, step, mean_ratio = (float(np.median([r[i] for r in runs])) for i in (0, 1, 2))
        ok = ratio <= 1.0
        missed += [] if ok else [kind]
        print(f"  {kind:<15} adapter {own:5.1f} us, FMU step {step:5.1f} us: {ratio:.2f}x "
              f"(runs {', '.join(f'{r:.2f}' for r in ratios)}; target <= 1x) {'PASS' if ok else 'MISS'}; "
              f"ratio of the means (slowest 1 % left out) {mean_ratio:.2f}x")
    if missed:
        print(f"MISS: adapter work above the FMU step for {', '.join(missed)}")
    return 1 if missed else 0


def _loop_context(fmu: Path, args: argparse.Namespace, poll_s: float) -> None:
    """The loopback lockstep loop (context, not the target): rate, round trip, busy time, null-server send."""
    replies = sample_replies(fmu)
    print(f"loopback context: {args.repeat} runs of {args.steps} lockstep steps, busy poll {args.busy_poll_us:.0f} "
          "us; medians per step (FMU step = setReal + doStep + getReal of the sent outputs through FMPy)")
    runs = [one_run(fmu, replies, args.steps, poll_s) for _ in range(args.repeat)]
    waits = reconnect_ms(fmu)
    print(f"px4 reconnect (connect -> first state, {len(waits)} times): median {np.median(waits):.2f} ms, max "
          f"{waits.max():.2f} ms (context, not a target)")
    for kind in runs[0]:
        for run in runs:
            r = run[kind]
            r["overhead_us"] = r["busy_us"] - r["fmu_us"]
            r["own_us"] = r["overhead_us"] - r["send_us"]
        m = {key: float(np.median([run[kind][key] for run in runs])) for key in runs[0][kind]}
        print(f"  {kind:<15} {m['rate']:5.0f} steps/s; round trip p50 {m['p50_us']:4.0f} us, p99 {m['p99_us']:4.0f} us;"
              f" busy - FMU step {m['overhead_us']:3.0f} us, of it the send alone {m['send_us']:3.0f} us; the rest "
              f"{m['own_us']:3.0f} us = {m['own_us'] / m['fmu_us']:.2f}x the FMU step in the loop (cold caches, "
              "another process waking: context, not the target)")


if __name__ == "__main__":
    raise SystemExit(main())
