"""One HIL session as a library call: ``serve(fmu, interface, config) -> HilResult``.

The CLI (``uavfmu hil``, ``uavfmu/commands/hil.py``) only parses arguments and prints what this returns.
SIGINT and SIGTERM (when called from the main thread) only set the stop flag: the loop ends between two
steps, never inside an FMU call, the summary is built and the FMU instance freed.
"""

from __future__ import annotations

import logging
import math
import signal
import threading
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fmu_models.config import ConfigError, validate_config
from fmu_models.fmi.host import FmuRunError
from fmu_models.signals.pwm_mapping import MappingError, PwmMapping
from hil_adapter.config import (
    DEFAULT_PORTS,
    INTERFACES,
    SPEED_RANGE,
    HilConfig,
    TimingSection,
    load_hil_config,
    sensor_suite,
)
from hil_adapter.core import Pacer, Plant, Recorder, Stats, Watchdog

log = logging.getLogger(__name__)
MAX_DURATION_S = 1e7  #: --duration-s bound (about 116 days)


class HilSetupError(ValueError):
    """The session could not start: a bad config, FMU, port or device; the message says which and why."""


@dataclass(frozen=True)
class HilResult:
    """What a session did: why it stopped, the summary figures (``Stats.summary``), the record written."""

    interface: str
    fmu: Path
    vehicle: str
    address: str
    stopped_by: str
    summary: dict[str, Any]
    record_path: Path | None = None
    record_rows: int = 0
    last_fmu_error: str = ""
    #: a fault that ended the session early (e.g. the FMU could not be instantiated again); "" otherwise
    error: str = ""
    #: recorded outputs whose prediction band the record holds (``--record-band``)
    band_outputs: tuple[str, ...] = ()

    def lines(self) -> list[str]:
        """The end-of-session console text."""
        out = [f"summary ({self.stopped_by}): " + ", ".join(f"{k} {v}" for k, v in self.summary.items())]
        oob = self.summary.get("out_of_band_steps", 0)
        if oob:
            out.append(f"warning: PWM above idle was outside the thrust map's trained band in {oob} steps "
                       "(record column out_of_band)")
        if self.last_fmu_error:
            out.append(f"last FMU error: {self.last_fmu_error}")
        if self.error:
            out.append(f"session ended early: {self.error}")
        if self.record_path is not None:
            out.append(f"record: {self.record_path} ({self.record_rows} rows"
                       + (f"; 5-95 % prediction band of {', '.join(self.band_outputs)}: columns <name>_band_lo|hi)"
                          if self.band_outputs else ")"))
        return out


@contextmanager
def stop_on_signals(stop: threading.Event, caught: list[str]) -> Iterator[None]:
    """SIGINT/SIGTERM set ``stop`` (and name themselves in ``caught``) instead of raising inside whatever runs;
    only from the main thread (elsewhere Python does not deliver signals), the old handlers come back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, _frame: Any) -> None:
        caught.append(signal.Signals(signum).name)
        stop.set()

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def serve(fmu: str | Path, interface: str, config: HilConfig | str | Path | None = None, *,
          host: str | None = None, port: int | None = None, record: str | Path | None = None,
          duration_s: float | None = None, stop: threading.Event | None = None,
          status: Callable[[str], None] | None = None, handle_signals: bool = True,
          speed: float | str | None = None, seed: int | None = None, record_band: bool = False,
          band_params: str | Path | None = None) -> HilResult:
    """Serve an autopilot from ``fmu`` over ``interface`` until ``stop`` is set, ``duration_s`` of wall time
    passes or SIGINT/SIGTERM arrives; ``status`` gets the live line every second. ``HilSetupError`` when the
    session cannot start (bad config, FMU, port); faults while running end up in the result, never raised.

    ``speed`` (``--speed``; overrides ``[timing] speed``, default 1): lockstep simulation seconds per wall
    second, ``"max"`` unpaced. ``seed`` (``--seed``; overrides ``[sensors] seed``): the sensor noise seed; with
    neither a fresh one is drawn. Both end up in the summary (``seed``, ``real_time_factor``). ``record_band``
    (``--record-band``, or ``[record] band``): the record also holds each output's prediction band
    (``hil_adapter.record_band``) from the ``discrepancy`` of ``band_params`` (``[record] band_params``), else of
    the parameter file embedded in the FMU."""
    if interface not in INTERFACES:
        raise HilSetupError(f"interface {interface!r}; allowed: {', '.join(INTERFACES)}")
    if duration_s is not None and not (math.isfinite(duration_s) and 0 < duration_s <= MAX_DURATION_S):
        raise HilSetupError(f"duration_s = {duration_s}; allowed > 0 and <= {MAX_DURATION_S:g} s")
    stop = stop or threading.Event()
    closers: list[Callable[[], Any]] = []
    try:
        cfg = config if isinstance(config, HilConfig) else load_hil_config(config)
        cfg = _with_options(cfg, interface, speed, seed)
        setup = _setup(Path(fmu), interface, cfg, host, port, record, closers, seed, record_band, band_params)
    except (ConfigError, MappingError, FmuRunError, OSError, ValueError) as err:
        _close_all(closers)
        raise HilSetupError(str(err)) from None
    server, plant, stats, recorder, address, sensors = setup
    caught: list[str] = []
    expired = threading.Event()

    def time_up() -> None:
        expired.set()
        stop.set()

    timer = threading.Timer(duration_s, time_up) if duration_s else None
    ticker = threading.Thread(target=_status, args=(stop, stats, plant, status), daemon=True)
    error = ""
    try:
        with stop_on_signals(stop, caught) if handle_signals else _nothing():
            if timer:
                timer.start()
            ticker.start()
            try:
                server.serve(stop=stop)
            except FmuRunError as err:  # the FMU could not be instantiated again: end with a clear message
                error = str(err)
    finally:
        stop.set()
        if timer:
            timer.cancel()
        summary = stats.summary(plant)
        summary["speed"] = "max" if cfg.speed is None else cfg.speed
        if sensors is not None:  # the noise seed: --seed N repeats this run's sensor noise
            summary["seed"] = sensors.seed
        _close_all(closers)
    stopped = (f"signal {caught[0]}" if caught else "error" if error else
               "duration" if expired.is_set() else "stopped")
    return HilResult(interface, Path(fmu), plant.vehicle, address, stopped, summary,
                     recorder.path if recorder else None, recorder.rows if recorder else 0, plant.last_error, error,
                     tuple(recorder.band.names) if recorder and recorder.band else ())


@contextmanager
def _nothing() -> Iterator[None]:
    yield


def _close_all(closers: list[Callable[[], Any]]) -> None:
    for close in reversed(closers):
        try:
            close()
        except OSError as err:  # a port that is already gone: nothing left to free
            log.debug("close failed: %s", err)
    closers.clear()


def parse_speed(text: str) -> float | str:
    """A ``--speed`` argument: ``"max"`` or a factor in ``SPEED_RANGE`` (``ValueError`` naming the range)."""
    if text.strip().lower() == "max":
        return "max"
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and SPEED_RANGE[0] <= value <= SPEED_RANGE[1]):
        raise ValueError(f"--speed {text!r}; allowed {SPEED_RANGE[0]:g}..{SPEED_RANGE[1]:g} or max")
    return value


def _with_options(cfg: HilConfig, interface: str, speed: float | str | None, seed: int | None) -> HilConfig:
    """``cfg`` with ``speed`` in ``[timing]``; options that would do nothing on this interface are errors."""
    if speed is not None:
        value = parse_speed(speed) if isinstance(speed, str) else speed
        timing = validate_config({**cfg.timing.model_dump(), "speed": value}, TimingSection, "--speed")
        cfg = cfg.model_copy(update={"timing": timing})
    lockstep = interface == "ardupilot-json" or (interface == "px4" and cfg.timing.mode == "lockstep")
    if cfg.speed != 1.0 and not lockstep:
        raise HilSetupError(f"speed {cfg.timing.speed}: only lockstep runs (px4 with [timing] mode = \"lockstep\", "
                            f"ardupilot-json) can run at another pace; {interface} "
                            f"{'in real time ' if interface == 'px4' else ''}follows the wall clock")
    if seed is not None and interface == "ardupilot-json" and cfg.sensors is None:
        raise HilSetupError("--seed: ardupilot-json adds sensor noise only with a [sensors] section (SITL "
                            "models its own otherwise)")
    if seed is not None and interface == "nmea":
        raise HilSetupError("--seed: the nmea interface sends the FMU's GPS truth, no sensor noise")
    return cfg


def _setup(fmu: Path, interface: str, cfg: HilConfig, host: str | None, port: int | None,
           record: str | Path | None, closers: list[Callable[[], Any]],
           seed: int | None = None, record_band: bool = False,
           band_params: str | Path | None = None) -> tuple[Any, Plant, Stats, Any, str, Any]:
    """Plant, sensors, recorder and the interface's server, each registered in ``closers`` as it is made;
    the sensor suite is the last item (None when the interface adds no sensor noise)."""
    mapping = PwmMapping.from_dict(cfg.mapping, "[mapping]") if cfg.mapping is not None else None
    sensors = sensor_suite(cfg, seed)
    watchdog = Watchdog(cfg.watchdog.timeout_s, cfg.watchdog.mode)
    dt = 1.0 / cfg.timing.rate_hz
    plant = Plant(fmu, mapping, cfg.start, start_time_s=dt)
    closers.append(plant.close)
    stats = Stats()
    rec_path = record or (cfg.record.path if cfg.record else None)
    band_params = band_params or (cfg.record.band_params if cfg.record else None)
    record_band = record_band or band_params is not None or bool(cfg.record and cfg.record.band)
    if record_band and not rec_path:
        raise HilSetupError("--record-band: the band is written into the record; give --record or [record] path")
    recorder = None
    if rec_path:
        band = None
        if record_band:
            from hil_adapter.record_band import RecordBand, read_band_discrepancy

            band = RecordBand(read_band_discrepancy(fmu, Path(band_params) if band_params else None), plant.outputs)
        channels = sorted({c.source for c in plant.mapping.channels})
        recorder = Recorder(rec_path, channels, list(plant.inputs), plant.outputs, band)
        closers.append(recorder.close)
    host = host or cfg.network.host
    port = port if port is not None else cfg.network.port
    port = port if port is not None else DEFAULT_PORTS.get(interface, 0)
    server = _make_server(interface, plant, sensors, stats, recorder, watchdog, host, port, dt, cfg, closers)
    if (interface == "ardupilot-json" and cfg.sensors is None) or interface == "nmea":
        sensors = None  # no sensor noise is sent: no seed to report
    if cfg.nmea is not None:
        sink, serial_port = nmea_sink(cfg)
        server.sinks.append(sink)
        closers.append(serial_port.close)
    elif interface == "nmea":
        raise HilSetupError("--interface nmea needs an [nmea] section with the serial port")
    address = getattr(server, "address", None)
    where = f"{address[0]}:{address[1]}" if isinstance(address, tuple) else f"{host}:{port}"
    return server, plant, stats, recorder, where if interface in DEFAULT_PORTS else interface, sensors


def nmea_sink(cfg: HilConfig) -> tuple[Callable[[float, Mapping[str, float]], None], Any]:
    """A step sink writing GGA/RMC/VTG to the configured serial port, and the port to close."""
    from hil_adapter.nmea import NmeaGpsWriter, open_serial

    assert cfg.nmea is not None
    port = open_serial(cfg.nmea.port, cfg.nmea.baud)
    writer = NmeaGpsWriter(port, cfg.nmea.rate_hz)

    def sink(t_s: float, s: Mapping[str, float]) -> None:
        writer.update(t_s, s["lat_deg"], s["lon_deg"], s["height_m"], s["vel_north_m_s"], s["vel_east_m_s"],
                      s["vel_down_m_s"])
        writer.poll(t_s)

    return sink, port


def _make_server(interface: str, plant: Plant, sensors: Any, stats: Stats, recorder: Recorder | None,
                 watchdog: Watchdog, host: str, port: int, dt: float, cfg: HilConfig,
                 closers: list[Callable[[], Any]]) -> Any:
    poll_s = cfg.timing.busy_poll_us * 1e-6
    if interface == "px4":
        from hil_adapter.px4 import Px4Server

        srv = Px4Server(plant, sensors, host, port, cfg.timing.mode == "lockstep", dt, stats, recorder, watchdog,
                        cfg.px4.rc_channels, wing_controls=cfg.wing_controls, busy_poll_s=poll_s, speed=cfg.speed)
        closers.append(srv.close)
        return srv
    if interface == "ardupilot-json":
        from hil_adapter.ardupilot_json import ArduPilotJsonServer, UdpTransport

        transport = UdpTransport(host, port, busy_poll_s=poll_s)
        closers.append(transport.close)
        # SITL models its own sensor noise: our noise goes on the IMU only when [sensors] asks for it
        srv = ArduPilotJsonServer(plant, transport, stats, recorder, sensors if cfg.sensors is not None else None,
                                  speed=cfg.speed)
        srv.address = transport.address
        return srv
    from hil_adapter.mavlink_bridge import MavlinkBridge, connect

    if interface == "mavlink":
        conn = connect(cfg.mavlink.url, cfg.mavlink.baud)
        closers.append(conn.close)
        return MavlinkBridge(plant, sensors, conn, dt, stats, recorder, watchdog)
    return NmeaOnly(plant, stats, dt)


class NmeaOnly:
    """``--interface nmea``: the FMU runs in real time on its failsafe or start inputs; GPS goes out as NMEA."""

    def __init__(self, plant: Plant, stats: Stats, dt: float) -> None:
        self.plant, self.stats, self.dt = plant, stats, dt
        self.sinks: list[Callable[[float, Mapping[str, float]], None]] = []

    def serve(self, stop: threading.Event) -> None:
        pacer = Pacer(self.dt, self.stats)
        while not stop.is_set():
            self.plant.advance(self.dt)
            self.stats.step(self.plant.out_of_band, self.dt)
            for sink in self.sinks:
                sink(self.plant.t_s, self.plant.state)
            pacer.wait()


def _status(stop: threading.Event, stats: Stats, plant: Plant, status: Callable[[str], None] | None) -> None:
    while not stop.wait(1.0):
        if status is not None:
            status(stats.line(plant))
