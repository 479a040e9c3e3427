"""Synthetic flight logs of the fixed-wing model: the project makes its own data (demo, tests, benchmarks).

The aircraft is flown open loop from trim with 3-2-1-1 multisteps on the surfaces and a throttle step,
simulated with the same compiled-equation RK4 step as the FMU, and written as a CSV log in the canonical
signal names of ``identification.logs.flightlog`` with the servo PWM an autopilot would have logged.
"""

from __future__ import annotations

import csv
import itertools
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fmu_models.common.atmosphere import eas_to_tas
from fmu_models.common.simulate import Simulator
from fmu_models.common.units import RAD_TO_DEG
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.fixed_wing.trim import trim
from fmu_models.quadrotor.constants import N_MOTORS
from fmu_models.signals.names import OUTPUT_TO_LOG
from fmu_models.signals.pwm_mapping import PwmMapping, ardupilot_servo_reversed, default_mapping
from identification.estimation.oem import Manoeuvre, OutputErrorEstimator
from identification.flights.scenarios import Recording
from identification.logs.dataflash_writer import MessageLayout, Stream

#: ArduPlane's default outputs: SERVO1 aileron, SERVO2 elevator, SERVO3 throttle, SERVO4 rudder
MAPPING = default_mapping("fixed_wing")

#: white sensor noise (1 sigma) per log column when ``noise=True``
NOISE = {"roll_rad": 0.003, "pitch_rad": 0.003, "yaw_rad": 0.003, "gyro_body_x_rad_s": 0.005,
         "gyro_body_y_rad_s": 0.005, "gyro_body_z_rad_s": 0.005, "accel_body_x_m_s2": 0.05,
         "accel_body_y_m_s2": 0.05, "accel_body_z_m_s2": 0.05, "airspeed_m_s": 0.1}


def multistep(t_s: np.ndarray, t0_s: float, unit_s: float, amp: float) -> np.ndarray:
    """The 3-2-1-1 multistep: +amp for 3 units, -amp for 2, +amp for 1, -amp for 1, from ``t0_s``."""
    edges = t0_s + unit_s * np.cumsum([0, 3, 2, 1, 1])
    out = np.zeros_like(t_s, dtype=float)
    for (a, b), s in zip(itertools.pairwise(edges), (1, -1, 1, -1), strict=True):
        out[(t_s >= a) & (t_s < b)] = s * amp
    return out


def fixed_wing_flight(params: FixedWingParams | None = None, seconds: float = 40.0, rate_hz: float = 50.0,
                      airspeed_m_s: float = 25.0, noise: bool = False, seed: int = 0
                      ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Times [s] and canonical log signals of an open-loop identification flight from trim at 100 m.

    Aileron, rudder and elevator 3-2-1-1 inputs repeat every 20 s; throttle steps +0.1 in the second
    half of each 20 s block.
    """
    sim = Simulator(FixedWingModel(params or FixedWingParams()))
    p = sim.params()
    tr = trim(sim.model, p, airspeed_m_s)
    dt = 1.0 / rate_hz
    n = round(seconds * rate_hz)
    t = np.arange(n + 1) * dt
    u = np.tile(tr.u, (n + 1, 1))
    for block in np.arange(0.0, seconds, 20.0):
        u[:, 0] += multistep(t, block + 1.0, 0.5, 0.05)
        u[:, 2] += multistep(t, block + 6.0, 0.5, 0.05)
        u[:, 1] += multistep(t, block + 11.0, 0.4, 0.03)
        u[:, 3] += np.where((t > block + 10.0) & (t < block + 18.0), 0.1, 0.0)
    signals = open_loop_signals(sim, p, tr.x, u, dt)
    if noise:
        rng = np.random.default_rng(seed)
        for col, sigma in NOISE.items():
            signals[col] += rng.normal(0.0, sigma, n + 1)
    return t, signals


def open_loop_signals(sim: Simulator, p: np.ndarray, x0: np.ndarray, u: np.ndarray, dt_s: float
                      ) -> dict[str, np.ndarray]:
    """The fixed wing flown open loop from state ``x0`` with the inputs ``u`` (one row per sample, ``dt_s``
    [s] apart): its outputs under their log names and the inputs as the servo PWM of ``MAPPING``, noise-free."""
    idx = sim.model.outputs.index
    _, _, y = sim.run(lambda t: u[round(t / dt_s)], p, (len(u) - 1) * dt_s, dt_s, x0=np.asarray(x0, dtype=float))
    signals = {col: y[:, idx[name]].copy() for name, col in OUTPUT_TO_LOG.items()}
    for ch in MAPPING.channels:
        values = u[:, sim.model.inputs.index[ch.target]]
        signals[f"servo_{ch.source}_pwm_us"] = np.array([ch.to_pwm(v) for v in values])
    return signals


def recording_signals(rec: Recording, noise: bool = False, seed: int = 0) -> dict[str, np.ndarray]:
    """Canonical log signals of an FMU flight (``identification.flights.scenarios.fly``): outputs under their log names
    and
    the inputs as the servo PWM an autopilot logs (quadrotor ``motor_k``/``servo_k``; wing via ``MAPPING``)."""
    signals = {col: np.asarray(rec.outputs[name], dtype=float).copy()
               for name, col in OUTPUT_TO_LOG.items() if name in rec.outputs}
    if noise:
        rng = np.random.default_rng(seed)
        for col, sigma in NOISE.items():
            if col in signals:
                signals[col] = signals[col] + rng.normal(0.0, sigma, len(rec.t_s))
    if "pwm_1_us" in rec.inputs:
        for k in range(1, N_MOTORS + 1):
            pwm = np.asarray(rec.inputs[f"pwm_{k}_us"], dtype=float)
            signals[f"servo_{k}_pwm_us"] = pwm
            signals[f"motor_{k}_pwm_us"] = pwm
    else:
        for ch in MAPPING.channels:
            signals[f"servo_{ch.source}_pwm_us"] = np.array([ch.to_pwm(v) for v in rec.inputs[ch.target]])
    return signals


def with_noise(signals: dict[str, np.ndarray], seed: int) -> dict[str, np.ndarray]:
    """``signals`` with seeded white sensor noise of ``NOISE`` on the columns it names (one flight, many logs)."""
    rng = np.random.default_rng(seed)
    return {c: v + rng.normal(0.0, NOISE[c], len(v)) if c in NOISE else v for c, v in signals.items()}


def write_csv_log(path: str | Path, t_s: np.ndarray, signals: dict[str, np.ndarray]) -> Path:
    """A CSV log (``time_s`` + one column per signal) that ``identification.logs.readers`` reads."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    names = list(signals)
    with p.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time_s", *names])
        for k in range(len(t_s)):
            w.writerow([repr(float(t_s[k])), *(repr(float(signals[n][k])) for n in names)])
    return p


def write_mapping_toml(path: str | Path, mapping: PwmMapping = MAPPING) -> Path:
    """The PWM mapping as the TOML file ``--mapping`` options read."""
    lines = []
    for c in mapping.channels:
        lines += [f"[channels.{c.target}]", f"source = {c.source}", f"min_us = {c.min_us}",
                  f"trim_us = {c.trim_us}", f"max_us = {c.max_us}", f"out_min = {c.out_min}", f"out_max = {c.out_max}",
                  f"reversed = {str(c.reversed).lower()}", ""]
    p = Path(path)
    p.write_text("\n".join(lines))
    return p


#: the output-error benchmark problem (bench/oem.py): derivatives of all axes, outputs of all axes, sensor noise (1
#: sigma)
OEM_FREE = ["C_ell_p", "C_ell_delta_a", "C_ell_beta", "C_ell_r", "C_n_beta", "C_n_r", "C_n_p", "C_n_delta_r",
        "C_n_delta_a", "C_Y_beta", "C_Y_delta_r", "C_m_alpha", "C_m_q", "C_m_delta_e", "C_m_0", "C_L_alpha",
        "C_L_0", "C_L_delta_e", "C_L_q", "C_ell_delta_r", "C_Y_delta_a", "C_D_delta_e", "e_oswald", "Jxz_kg_m2",
        "C_T0"]
OEM_OUTPUTS = ["roll_rad", "pitch_rad", "rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s",
           "accel_body_x_m_s2", "accel_body_y_m_s2", "accel_body_z_m_s2", "airspeed_m_s", "beta_rad"]
OEM_SIGMA = np.array([0.003, 0.003, 0.005, 0.005, 0.005, 0.05, 0.05, 0.05, 0.1, 0.003])


def identification_manoeuvres(oe: OutputErrorEstimator, p: np.ndarray, seconds: float, rate: float, count: int,
                              rng: np.random.Generator | None, sigma: np.ndarray | None = None) -> list[Manoeuvre]:
    """``count`` manoeuvres of ``seconds`` at ``rate`` Hz cycling through four designs (lateral, longitudinal,
    all three surfaces, lateral + longitudinal), each from a trim between 22 and 28 m/s with a throttle step,
    simulated by ``oe`` with the parameters ``p``; noise of std ``sigma`` (per output of ``oe``) from ``rng``."""
    dt = 1.0 / rate
    n = int(seconds * rate)
    t = np.arange(n) * dt
    out = []
    for i in range(count):
        j, va = i % 4, float(np.linspace(22.0, 28.0, count)[i])
        tr = trim(oe.model, p, va)
        u = np.tile(tr.u, (n, 1))
        if j in (0, 3):
            u[:, 0] += multistep(t, 1.0, 0.5, 0.05)
            u[:, 2] += multistep(t, 6.0, 0.5, 0.05)
        if j in (1, 3):
            u[:, 1] += multistep(t, 1.0 + 9 * (j == 3), 0.4, 0.03)
        if j == 2:
            u[:, 0] += multistep(t, 1.0, 0.4, 0.04)
            u[:, 1] += multistep(t, 5.0, 0.5, 0.02)
            u[:, 2] += multistep(t, 9.0, 0.4, 0.04)
        u[:, 3] += np.where((t > 0.6 * seconds) & (t < 0.9 * seconds), 0.1, 0.0)
        y, _, _ = oe.simulate(p[oe.i_free], Manoeuvre(tr.x, u, np.zeros((n, len(oe.outputs))), dt),
                              sensitivities=False)
        if rng is not None and sigma is not None:
            y = y + rng.normal(0.0, sigma, y.shape)
        out.append(Manoeuvre(tr.x, u, y, dt, f"trim {va:g} m/s"))
    return out


def ardupilot_params(vehicle: str) -> dict[str, float]:
    """The ArduPilot parameters a log of ``vehicle`` carries for its output mapping (``SERVOn_*``)."""
    if vehicle == "quadrotor":
        out = {"FRAME_CLASS": 1.0, "FRAME_TYPE": 1.0}
        for k in range(1, N_MOTORS + 1):
            out |= {f"SERVO{k}_FUNCTION": 32.0 + k, f"SERVO{k}_MIN": 1000.0, f"SERVO{k}_MAX": 2000.0}
        return out
    functions = {"aileron_rad": 4, "elevator_rad": 19, "throttle": 70, "rudder_rad": 21}
    out = {}
    for ch in MAPPING.channels:
        n = ch.source
        out |= {f"SERVO{n}_FUNCTION": float(functions[ch.target]), f"SERVO{n}_MIN": ch.min_us,
                f"SERVO{n}_TRIM": ch.trim_us, f"SERVO{n}_MAX": ch.max_us,
                f"SERVO{n}_REVERSED": float(ardupilot_servo_reversed(ch))}
    return out


#: every how many recording samples each message is logged (a 100 Hz recording: IMU 100 Hz, ATT and RCOU
#: 50 Hz, GPS 5 Hz), like ArduPilot's default rates
LOG_DECIMATION = {"IMU": 1, "ATT": 2, "RCOU": 2, "GPS": 20, "CTUN": 4, "BARO": 2, "ARSP": 4}


def write_log(path: str | Path, rec: Recording, noise: bool = False, seed: int = 0, boot_s: float = 0.0,
              extra: Mapping[str, Stream] | None = None, layouts: Sequence[MessageLayout] = (),
              decimation: Mapping[str, int] | None = None) -> Path:
    """An ArduPilot DataFlash ``.bin`` log of an FMU flight, as the autopilot would have written it: IMU, ATT
    (degrees), RCOU (integer PWM), CTUN/BARO altitude, GPS, ARSP for the wing, at the rates of
    ``LOG_DECIMATION``, the ``SERVOn_*`` parameters, and seeded white sensor noise when ``noise``. The recording
    starts ``boot_s`` [s] after boot (TimeUS); ``extra`` adds messages ``{name: (t_s since boot, columns)}``
    (e.g. EXCT marks, MODE), with their ``layouts`` when they are not standard ones; ``decimation`` overrides
    entries of ``LOG_DECIMATION`` (e.g. ``{"RCOU": 1}``: every servo command logged)."""
    from identification.logs.dataflash_writer import write_log as write_dataflash

    sig = recording_signals(rec, noise=noise, seed=seed)
    t = np.asarray(rec.t_s, dtype=float) + boot_s
    vehicle = "quadrotor" if "pwm_1_us" in rec.inputs else "fixed_wing"
    deg = RAD_TO_DEG
    columns: dict[str, dict[str, Any]] = {
        "IMU": {"I": 0, "GyrX": sig["gyro_body_x_rad_s"], "GyrY": sig["gyro_body_y_rad_s"],
                "GyrZ": sig["gyro_body_z_rad_s"], "AccX": sig["accel_body_x_m_s2"],
                "AccY": sig["accel_body_y_m_s2"], "AccZ": sig["accel_body_z_m_s2"]},
        "ATT": {"DesRoll": 0.0, "Roll": sig["roll_rad"] * deg, "DesPitch": 0.0, "Pitch": sig["pitch_rad"] * deg,
                "DesYaw": 0.0, "Yaw": np.mod(sig["yaw_rad"] * deg, 360.0)},
        "RCOU": {f"C{k}": np.round(sig[f"servo_{k}_pwm_us"]) for k in range(1, 15) if f"servo_{k}_pwm_us" in sig},
        "GPS": {"I": 0, "Status": 3, "NSats": 14, "HDop": 0.7, "Lat": sig["lat_deg"], "Lng": sig["lon_deg"],
                "Alt": sig["altitude_m"], "Spd": np.hypot(sig["vel_north_m_s"], sig["vel_east_m_s"]),
                "GCrs": np.mod(np.degrees(np.arctan2(sig["vel_east_m_s"], sig["vel_north_m_s"])), 360.0),
                "VZ": sig["vel_down_m_s"]},
        ("CTUN" if vehicle == "quadrotor" else "BARO"): {"Alt": sig["altitude_m"]},
    }
    if vehicle == "fixed_wing":
        # the autopilot logs the equivalent airspeed at the AMSL altitude it knows (here GPS.Alt), as SITL makes it
        columns["ARSP"] = {"I": 0, "Airspeed": sig["airspeed_m_s"] / eas_to_tas(sig["altitude_m"]), "U": 1, "H": 1}
    streams: dict[str, Any] = {}
    for name, cols in columns.items():
        k = {**LOG_DECIMATION, **(decimation or {})}[name]
        streams[name] = (t[::k], {c: (v[::k] if isinstance(v, np.ndarray) else v) for c, v in cols.items()})
    streams["EV"] = (t[:1], {"Id": 10})  # armed at the start
    streams.update(extra or {})
    return write_dataflash(path, streams, ardupilot_params(vehicle), layouts)
