"""Where a log is on the ground: the take-off guess for a log with no idle phase, and the ``landed`` flag."""

from __future__ import annotations

import numpy as np

from identification.logs.flightlog import FlightLog, Signal
from identification.logs.log_state import GROUND_HEIGHT_M, TAKEOFF_RISE_M, ground_level, ground_samples, takes_off
from tests.conftest import shared_data

T = np.arange(0.0, 60.0, 0.02)


def _log(alt: np.ndarray, landed: np.ndarray | None = None) -> FlightLog:
    """A quadrotor log hovering (motors at 1500 us, never idle) along ``alt`` [m]."""
    sig = {"altitude_m": Signal("altitude_m", T, alt, "m", "test")}
    sig |= {f"motor_{k}_pwm_us": Signal(f"motor_{k}_pwm_us", T, np.full(len(T), 1500.0), "us", "test")
            for k in range(1, 5)}
    if landed is not None:
        sig["landed"] = Signal("landed", T, landed, "", "test")
    return FlightLog("test.log", "synthetic", sig, {}, "quadrotor")


def _takeoff() -> np.ndarray:
    """Run-up on the ground at 0 m for 3 s, then a climb at 1 m/s to 5 m."""
    return np.clip(T - 3.0, 0.0, 5.0)


def _hover_start() -> np.ndarray:
    """A log started in a hover at 10 m: a throttle input lifts it 0.5 m and back at 20 s, a 2 m climb at 40 s."""
    bob = 0.5 * np.exp(-((T - 20.0) / 1.0) ** 2)
    return 10.0 + bob + np.clip(T - 40.0, 0.0, 2.0)


def test_a_take_off_without_idle_phase_is_on_the_ground_until_it_climbs():
    alt = _takeoff()
    assert takes_off(alt)
    log = _log(alt)
    assert ground_level(log, "quadrotor", T, np.zeros(len(T), bool)) == 0.0
    ground = np.any(list(ground_samples(log, "quadrotor", T, 1100.0).values()), axis=0)
    assert ground[T < 3.0].all() and not ground[T > 3.0 + GROUND_HEIGHT_M["quadrotor"] + 0.05].any()


def test_a_log_started_in_a_hover_is_airborne_throughout():
    """Its first departure from the start band comes back (a throttle input): not a take-off, even though the
    log starts at its lowest point and later climbs more than ``TAKEOFF_RISE_M``."""
    alt = _hover_start()
    assert alt[0] == alt.min() and alt.max() - alt[0] > TAKEOFF_RISE_M  # what the old guess took for a take-off
    assert not takes_off(alt)
    log = _log(alt)
    assert ground_level(log, "quadrotor", T, np.zeros(len(T), bool)) is None
    assert not np.any(list(ground_samples(log, "quadrotor", T, 1100.0).values()))


def test_a_landed_flag_never_set_rules_out_the_take_off_guess():
    log = _log(_takeoff(), landed=np.zeros(len(T)))
    assert ground_level(log, "quadrotor", T, np.zeros(len(T), bool)) is None
    flagged = _log(_takeoff(), landed=(T < 3.5).astype(float))
    ground = np.any(list(ground_samples(flagged, "quadrotor", T, 1100.0).values()), axis=0)
    assert ground[T < 3.5].all() and not ground[T > 4.0].any()


def test_px4_logs_carry_the_land_detector_flag():
    from identification.logs.readers import read_log

    log = read_log(shared_data("quadrotor_px4_sitl", "px4_sitl_fmu_sysid.ulg"))
    landed = log.signal("landed")
    assert landed.resample(np.array([0.5]))[0] == 1.0  # on the ground before the take-off
    assert landed.resample(np.array([log.duration_s / 2]))[0] == 0.0  # flying mid-log
