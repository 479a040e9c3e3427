"""The drag regression's body velocity across yaw's +-pi seam."""

from __future__ import annotations

import numpy as np

from identification.logs.flightlog import FlightLog, Signal
from identification.quadrotor.identify import _body_velocity


def test_body_velocity_between_samples_on_either_side_of_the_yaw_seam():
    t = np.array([0.0, 0.1])
    yaw = np.array([np.pi - 0.05, -np.pi + 0.05])  # heading south, 0.1 rad turned through the seam
    sig = {"roll_rad": np.zeros(2), "pitch_rad": np.zeros(2), "yaw_rad": yaw,
           "vel_north_m_s": np.full(2, -1.0), "vel_east_m_s": np.zeros(2), "vel_down_m_s": np.zeros(2)}
    log = FlightLog("seam", "synthetic", {n: Signal(n, t, v, "", "") for n, v in sig.items()}, {}, "quadrotor")
    v = _body_velocity(log, np.array([0.05]))[0]
    # at the seam the nose points south: flying south at 1 m/s is 1 m/s forward (plain interpolation: yaw 0, -1)
    np.testing.assert_allclose(v, [1.0, 0.0, 0.0], atol=1e-9)
