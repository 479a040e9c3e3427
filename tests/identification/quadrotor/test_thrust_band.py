"""identify quadrotor says where the motors ran against the thrust map's trained band, and warns when the map is
extrapolated over more than a small share of the fit windows' motor samples."""

from __future__ import annotations

import dataclasses

import numpy as np

from fmu_models.quadrotor.anfis import AnfisMap
from fmu_models.quadrotor.params import QuadrotorParams
from identification.logs.flightlog import FlightLog, Signal
from identification.quadrotor import identify as q
from identification.quadrotor.segments import Segment


def _log(pwm_us: np.ndarray, rate_hz: float = 250.0) -> FlightLog:
    """Four motors at ``pwm_us`` (n x 4) logged at ``rate_hz``."""
    t = np.arange(len(pwm_us)) / rate_hz
    sig = {f"motor_{k}_pwm_us": Signal(f"motor_{k}_pwm_us", t, pwm_us[:, k - 1], "us") for k in range(1, 5)}
    return FlightLog("band.bin", "synthetic", sig, {}, "quadrotor")


def _feature_map(lo: float, hi: float) -> QuadrotorParams:
    """The default quadrotor with a one-rule feature map (``u^2, u``) trained on commands ``lo..hi``, idle at
    1000 us (``identify thrust``'s default; the published map's quadrotor idles at 1100 us)."""
    amap = AnfisMap(("u",), "gaussian", ((0.5,),), ((1.0,),), None, 1, ((9.0, 1.0),), ((lo, hi),),
                    features=("x2", "x"))
    return dataclasses.replace(QuadrotorParams(), thrust_map=amap, pwm_idle_us=1000.0)


def test_band_in_pwm_for_both_kinds_of_map() -> None:
    # the published map is trained on the summed PWM 5800-6217.3 us: per motor a quarter of it
    lo, hi = q.thrust_band_pwm_us(QuadrotorParams())
    assert (lo, hi) == (5800.0 / 4, QuadrotorParams().thrust_map.input_range[0][1] / 4)
    # a feature map's band is in command u = (pwm - idle) / (full - idle), here over 1000-2000 us
    assert q.thrust_band_pwm_us(_feature_map(0.42, 1.0)) == (1420.0, 2000.0)


def test_motors_inside_the_band_give_no_warning() -> None:
    rng = np.random.default_rng(0)
    pwm = 1500.0 + rng.uniform(-70.0, 70.0, (1000, 4))
    cov = q.thrust_band_coverage([_log(pwm)], [(0, Segment(0.0, 4.0, "roll"))], _feature_map(0.42, 1.0))
    assert cov["share_outside"] == 0.0 and cov["warning"] == ""
    assert 1430.0 < cov["flown_pwm_us"][0] < 1440.0 and 1560.0 < cov["flown_pwm_us"][1] < 1570.0


def test_motors_beyond_the_band_are_counted_and_warned_about() -> None:
    # a tenth of the samples below the band (1380 us), a twentieth above it (1850 us), in the window only
    pwm = np.full((2000, 4), 1530.0)
    pwm[:100] = 1380.0
    pwm[100:150] = 1850.0
    pwm[1500:] = 1300.0  # after the window: not counted
    cov = q.thrust_band_coverage([_log(pwm)], [(0, Segment(0.0, 4.0, "roll"))], _feature_map(0.42, 0.8))
    assert np.isclose(cov["share_below"], 0.1) and np.isclose(cov["share_above"], 0.05)
    assert cov["band_pwm_us"] == [1420.0, 1800.0]
    assert "1420-1800 us" in cov["warning"] and "Jx, Jy" in cov["warning"]
    assert "warning: " + cov["warning"] in cov["text"]
    # just under the threshold: stated, not warned about
    pwm[:150] = 1530.0
    pwm[100:108] = 1850.0
    cov = q.thrust_band_coverage([_log(pwm)], [(0, Segment(0.0, 4.0, "roll"))], _feature_map(0.42, 0.8))
    assert 0.0 < cov["share_outside"] <= q.BAND_WARN_SHARE and cov["warning"] == ""
