"""``uavfmu hil FMU --interface px4|ardupilot-json|mavlink|nmea [--config bench.toml]``.

Serves an autopilot from the FMU until Ctrl-C (or ``--duration-s`` of wall time), printing a live status
line and a summary at exit. Config (TOML, every section optional; unknown keys are errors)::

    [network]    host = "127.0.0.1"   port = 4560       # PX4 TCP / JSON UDP; 127.0.0.1 unless told otherwise
    [timing]     mode = "lockstep"    rate_hz = 250     # PX4: lockstep or realtime; MAVLink/NMEA: realtime
                 busy_poll_us = 500                      # lockstep: poll this long before a blocking receive
    [watchdog]   timeout_s = 0.5      mode = "throttle_off"   # or "hold"
    [record]     path = "hil_log.csv"                    # every step in and out, readable by our readers
    [mavlink]    url = "udpin:127.0.0.1:14560"  baud = 57600
    [nmea]       port = "/dev/ttyUSB0"  baud = 38400  rate_hz = 5     # GPS sentences beside any interface
    [px4]        rc_channels = [1500, 1500, 1000, 1500]  # RC_CHANNELS sent with each heartbeat (PWM)
                 wing_controls = {"1" = 0, "2" = 1, "3" = 3, "4" = 2}  # fixed wing: output channel -> control
    [start]      init_pos_down_m = 0.0                    # FMU start values
    [sensors]    seed = 0  [sensors.gyro] noise_std = 0.002 ...        # hil_adapter.sensors.SensorConfig
    [mapping.channels.aileron_rad] source = 1 ...                      # fmu_models.signals.pwm_mapping

Exit status: 0 after a clean stop, 2 bad config or FMU.
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
import tomllib
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

SECTIONS = {"network": {"host", "port"}, "px4": {"rc_channels", "wing_controls"},
            "timing": {"mode", "rate_hz", "busy_poll_us"}, "watchdog": {"timeout_s", "mode"},
            "record": {"path"}, "mavlink": {"url", "baud"}, "nmea": {"port", "baud", "rate_hz"}, "start": None,
            "sensors": None, "mapping": None}
INTERFACES = ("px4", "ardupilot-json", "mavlink", "nmea")
DEFAULT_PORTS = {"px4": 4560, "ardupilot-json": 9002}


class HilConfigError(ValueError):
    """A bad bench config: names the file, the key and the value."""


def load_config(path: Path | None) -> dict[str, Any]:
    if path is None:
        return {}
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise HilConfigError(f"{path}: cannot read the config ({err})") from err
    problems = []
    for key, value in data.items():
        if key not in SECTIONS:
            problems.append(f"[{key}] is not a section (known: {', '.join(SECTIONS)})")
        elif not isinstance(value, dict):
            problems.append(f"{key} must be a table")
        elif SECTIONS[key] is not None:
            problems += [f"{key}.{k} is not a setting (known: {', '.join(sorted(SECTIONS[key]))})"
                         for k in value if k not in SECTIONS[key]]
    timing = data.get("timing", {})
    if timing.get("mode", "lockstep") not in ("lockstep", "realtime"):
        problems.append(f"timing.mode = {timing['mode']!r}; allowed: lockstep, realtime")
    rate = timing.get("rate_hz", 250)
    if not (isinstance(rate, int | float) and 1 <= rate <= 10000):
        problems.append(f"timing.rate_hz = {rate!r}; allowed: 1..10000")
    poll = timing.get("busy_poll_us", 0)
    if not (isinstance(poll, int | float) and not isinstance(poll, bool) and 0 <= poll <= 100_000):
        problems.append(f"timing.busy_poll_us = {poll!r}; allowed: 0..100000 (0 turns the busy poll off)")
    if problems:
        raise HilConfigError(f"{path}: " + "; ".join(problems))
    return data


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__.split("\n\n")[0]
    parser.add_argument("fmu", type=Path)
    parser.add_argument("--interface", choices=INTERFACES, required=True)
    parser.add_argument("--config", type=Path, help="bench TOML (see the module docstring)")
    parser.add_argument("--host", help="bind address (default 127.0.0.1)")
    parser.add_argument("--port", type=int, help="PX4 TCP port (4560) or JSON UDP port (9002)")
    parser.add_argument("--record", type=Path, help="CSV log of every step (overrides [record] path)")
    parser.add_argument("--duration-s", type=float, help="stop after this much wall time")
    parser.add_argument("--quiet", action="store_true", help="no live status line")


def nmea_sink(cfg: Mapping[str, Any]) -> tuple[Callable[[float, Mapping[str, float]], None], Any]:
    """A step sink writing GGA/RMC/VTG to the configured serial port, and the port to close."""
    from hil_adapter.nmea import NmeaGpsWriter, open_serial

    port = open_serial(str(cfg["port"]), int(cfg.get("baud", 38400)))
    writer = NmeaGpsWriter(port, float(cfg.get("rate_hz", 5.0)))

    def sink(t_s: float, s: Mapping[str, float]) -> None:
        writer.update(t_s, s["lat_deg"], s["lon_deg"], s["height_m"], s["vel_north_m_s"], s["vel_east_m_s"],
                      s["vel_down_m_s"])
        writer.poll(t_s)

    return sink, port


def run(args: argparse.Namespace) -> int:
    from fmu_models.fmi.host import FmuRunError
    from fmu_models.signals.pwm_mapping import PwmMapping
    from hil_adapter.core import Plant, Recorder, Stats, Watchdog
    from hil_adapter.sensors import SensorConfig, SensorSuite

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    closers: list[Callable[[], Any]] = []
    try:
        cfg = load_config(args.config)
        src = str(args.config or "defaults")
        mapping = PwmMapping.from_dict(cfg["mapping"], f"{src} [mapping]") if "mapping" in cfg else None
        sensors_cfg = dict(cfg.get("sensors", {}))
        seed = int(sensors_cfg.pop("seed", 0))
        sensors = SensorSuite(SensorConfig.from_dict(sensors_cfg, f"{src} [sensors]"), seed=seed)
        watchdog = Watchdog(**cfg.get("watchdog", {}))
        plant = Plant(args.fmu, mapping, cfg.get("start"))
        closers.append(plant.close)
        stats = Stats()
        rec_path = args.record or (Path(cfg["record"]["path"]) if "record" in cfg else None)
        recorder = None
        if rec_path:
            channels = sorted({c.source for c in plant.mapping.channels})
            recorder = Recorder(rec_path, channels, list(plant.inputs), plant.outputs)
            closers.append(recorder.close)
        host = args.host or cfg.get("network", {}).get("host", "127.0.0.1")
        port = args.port or cfg.get("network", {}).get("port", DEFAULT_PORTS.get(args.interface, 0))
        timing = cfg.get("timing", {})
        dt = 1.0 / float(timing.get("rate_hz", 250))
        server = _make_server(args.interface, plant, sensors, stats, recorder, watchdog, host, port, dt, timing, cfg,
                              closers)
        if "nmea" in cfg or args.interface == "nmea":
            if "nmea" not in cfg:
                raise HilConfigError(f"{src}: --interface nmea needs an [nmea] section with the serial port")
            sink, serial_port = nmea_sink(cfg["nmea"])
            server.sinks.append(sink)
            closers.append(serial_port.close)
    except (HilConfigError, ValueError, OSError, FmuRunError) as err:
        for close in reversed(closers):
            close()
        print(f"uavfmu hil: error: {err}", file=sys.stderr)
        return 2

    stop = threading.Event()
    status = threading.Thread(target=_status, args=(stop, stats, plant, args.quiet), daemon=True)
    status.start()
    timer = threading.Timer(args.duration_s, stop.set) if args.duration_s else None
    if timer:
        timer.start()
    print(f"uavfmu hil: {args.interface} serving {args.fmu.name} ({plant.vehicle}) on {host}:{port}"
          if args.interface in DEFAULT_PORTS else f"uavfmu hil: {args.interface} serving {args.fmu.name}")
    try:
        server.serve(stop=stop)
    except KeyboardInterrupt:
        pass
    finally:
        stop.set()
        if timer:
            timer.cancel()
        for close in reversed(closers):
            close()
    print("\nsummary: " + ", ".join(f"{k} {v}" for k, v in stats.summary(plant).items()))
    if plant.last_error:
        print(f"last FMU error: {plant.last_error}")
    if recorder is not None:
        print(f"record: {recorder.path} ({recorder.rows} rows)")
    return 0


def _make_server(interface: str, plant: Any, sensors: Any, stats: Any, recorder: Any, watchdog: Any, host: str,
                 port: int, dt: float, timing: Mapping[str, Any], cfg: Mapping[str, Any],
                 closers: list[Callable[[], Any]]) -> Any:
    from hil_adapter.core import BUSY_POLL_S

    poll_s = float(timing["busy_poll_us"]) * 1e-6 if "busy_poll_us" in timing else BUSY_POLL_S
    if interface == "px4":
        from hil_adapter.px4 import Px4Server

        srv = Px4Server(plant, sensors, host, port, timing.get("mode", "lockstep") == "lockstep", dt, stats,
                        recorder, watchdog, cfg.get("px4", {}).get("rc_channels"),
                        wing_controls=_wing_controls(cfg.get("px4", {}).get("wing_controls")), busy_poll_s=poll_s)
        closers.append(srv.close)
        return srv
    if interface == "ardupilot-json":
        from hil_adapter.ardupilot_json import ArduPilotJsonServer, UdpTransport

        transport = UdpTransport(host, port, busy_poll_s=poll_s)
        closers.append(transport.close)
        # SITL models its own sensor noise: our noise goes on the IMU only when [sensors] asks for it
        return ArduPilotJsonServer(plant, transport, stats, recorder, sensors if "sensors" in cfg else None)
    from hil_adapter.mavlink_bridge import MavlinkBridge, connect

    if interface == "mavlink":
        mav = cfg.get("mavlink", {})
        conn = connect(str(mav.get("url", "udpin:127.0.0.1:14560")), int(mav.get("baud", 57600)))
        closers.append(conn.close)
        return MavlinkBridge(plant, sensors, conn, dt, stats, recorder, watchdog)
    return _NmeaOnly(plant, stats, dt, watchdog)


def _wing_controls(raw: Any) -> dict[int, int] | None:
    """``[px4] wing_controls`` (TOML keys are strings) as output channel -> control index."""
    if raw is None:
        return None
    try:
        return {int(k): int(v) for k, v in dict(raw).items()}
    except (TypeError, ValueError):
        raise HilConfigError(f"px4.wing_controls = {raw!r}: a table of output channel -> control index") from None


class _NmeaOnly:
    """``--interface nmea``: the FMU runs in real time on its failsafe or start inputs; GPS goes out as NMEA."""

    def __init__(self, plant: Any, stats: Any, dt: float, watchdog: Any) -> None:
        self.plant, self.stats, self.dt, self.watchdog = plant, stats, dt, watchdog
        self.sinks: list[Callable[[float, Mapping[str, float]], None]] = []

    def serve(self, stop: threading.Event) -> None:
        from hil_adapter.core import Pacer

        pacer = Pacer(self.dt, self.stats)
        while not stop.is_set():
            self.plant.advance(self.dt)
            self.stats.steps += 1
            for sink in self.sinks:
                sink(self.plant.t_s, self.plant.state)
            pacer.wait()


def _status(stop: threading.Event, stats: Any, plant: Any, quiet: bool) -> None:
    while not stop.wait(1.0):
        if not quiet:
            print("\r" + stats.line(plant), end="", flush=True)
