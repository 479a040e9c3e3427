"""Fake autopilots for the HIL tests: a quadrotor altitude/attitude controller on top of what an autopilot
receives (state estimates), and helpers to turn interface messages into the controller's inputs."""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from uavfmu.scenarios import QuadrotorAutopilot, published_thrust_inverse


def euler_from_quat(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def body_velocity(q: tuple[float, float, float, float], v_ned: tuple[float, float, float]) -> np.ndarray:
    w, x, y, z = q
    r_b2n = np.array([
        [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
    ])
    return r_b2n.T @ np.asarray(v_ned)


def controller_inputs(q: tuple[float, float, float, float], rates: tuple[float, float, float],
                      altitude_m: float, v_ned: tuple[float, float, float]) -> dict[str, float]:
    roll, pitch, yaw = euler_from_quat(*q)
    vb = body_velocity(q, v_ned)
    return {"altitude_m": altitude_m, "vel_down_m_s": v_ned[2], "roll_rad": roll, "pitch_rad": pitch,
            "yaw_rad": yaw, "rate_body_x_rad_s": rates[0], "rate_body_y_rad_s": rates[1],
            "rate_body_z_rad_s": rates[2], "vel_body_x_m_s": vb[0], "vel_body_y_m_s": vb[1]}


def hold_10m_autopilot() -> QuadrotorAutopilot:
    return QuadrotorAutopilot(lambda t: 10.0, published_thrust_inverse())


@contextmanager
def serving(server: Any, **serve_kwargs: Any) -> Iterator[Any]:
    """Run ``server.serve(stop=...)`` in a thread for the duration of the block; always stop and join it."""
    stop = threading.Event()
    th = threading.Thread(target=server.serve, kwargs={"stop": stop, **serve_kwargs}, daemon=True)
    th.start()
    try:
        yield server
    finally:
        stop.set()
        th.join(timeout=10)
