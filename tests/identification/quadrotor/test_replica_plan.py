"""The replica flies a stick plan of ``uavfmu excite --vehicle quadrotor`` with the plan's signs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fmu_models.quadrotor.params import QuadrotorParams
from identification.flights.quadrotor_replica import MAX_TILT_RAD, fly_replica


@dataclass
class _Block:
    start_s: float
    end_s: float
    axis: str


class _Plan:
    """Roll stick +0.3 (right side down) over 0.5-1.5 s, then pitch stick +0.3 (nose up) over 2-3 s."""

    def __init__(self) -> None:
        self.blocks = [_Block(0.5, 2.0, "roll"), _Block(2.0, 3.5, "pitch")]
        self.duration_s = 3.5

    def sticks(self, t_s: np.ndarray) -> np.ndarray:
        out = np.zeros((len(t_s), 4))
        out[(t_s >= 0.5) & (t_s < 1.5), 0] = 0.3
        out[(t_s >= 2.0) & (t_s < 3.0), 1] = 0.3
        return out


def test_replica_flies_the_plans_sticks_and_keeps_its_blocks():
    flight = fly_replica(QuadrotorParams(), rate_hz=100.0, sim_hz=400.0, plan=_Plan())
    roll, pitch = flight.log.signal("roll_rad"), flight.log.signal("pitch_rad")
    assert roll.resample(np.array([1.4]))[0] > 0.8 * 0.3 * MAX_TILT_RAD  # right side down: positive roll
    assert abs(roll.resample(np.array([2.9]))[0]) < 0.02
    assert pitch.resample(np.array([2.9]))[0] > 0.8 * 0.3 * MAX_TILT_RAD  # nose up: positive pitch
    assert [b.axis for b in flight.blocks] == ["roll", "pitch"] and roll.t_s[-1] >= 3.5
