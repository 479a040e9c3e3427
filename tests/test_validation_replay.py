"""Replay of a recorded closed-loop flight through the quadrotor FMU: near-perfect with the same model,
worse with a wrong mass; windows re-initialise from the recorded state."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from identification.validation import ValidationError, replay
from uavfmu.scenarios import QuadrotorAutopilot, fly, published_thrust_inverse

SIGNALS = ["altitude_m", "roll_rad", "pitch_rad", "yaw_rad"]


@pytest.fixture(scope="module")
def flight(quadrotor_fmu: Path):
    ap = QuadrotorAutopilot(lambda t: 0.0 if t < 1 else 6.0, published_thrust_inverse(), gravity_m_s2=9.8069,
                            yaw_rad=lambda t: 0.3 if t > 5 else 0.0)
    return fly(quadrotor_fmu, ap, 12.0, 0.02)


def test_same_model_replays_the_flight(quadrotor_fmu: Path, flight) -> None:
    res = replay(quadrotor_fmu, flight.t_s, flight.inputs, flight.outputs, SIGNALS)
    m = res.windows[0].metrics["altitude_m"]
    assert m.rmse < 1e-6 and m.theil_u < 1e-6
    assert flight.outputs["altitude_m"].max() > 4.0  # the flight went somewhere


def test_wrong_mass_scores_worse_and_windows_limit_the_drift(quadrotor_fmu: Path, flight) -> None:
    full = replay(quadrotor_fmu, flight.t_s, flight.inputs, flight.outputs, SIGNALS, start_values={"mass_kg": 1.3})
    windows = replay(quadrotor_fmu, flight.t_s, flight.inputs, flight.outputs, SIGNALS, window_s=2.0,
                     start_values={"mass_kg": 1.3})
    rmse_full = full.windows[0].metrics["altitude_m"].rmse
    assert rmse_full > 0.5
    assert len(windows.windows) == 6
    assert windows.overall("altitude_m").rmse < rmse_full


def test_missing_signal_is_named(quadrotor_fmu: Path, flight) -> None:
    measured = {k: v for k, v in flight.outputs.items() if k != "yaw_rad"}
    with pytest.raises(ValidationError, match="yaw_rad"):
        replay(quadrotor_fmu, flight.t_s, flight.inputs, measured, SIGNALS)
    assert np.all(np.isfinite(flight.outputs["altitude_m"]))
