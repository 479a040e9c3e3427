"""Battery state without a voltage log: the hover-condition thrust scale and its FMU delivery."""

from __future__ import annotations

import numpy as np
import pytest

from fmu_models.common.units import G0_M_S2
from identification.thrust.battery import equivalent_voltage_V, hover_thrust_scale


def test_constant_battery_is_recovered_exactly_and_the_start_uses_the_first_window() -> None:
    t = np.arange(0.0, 200.0, 0.1)
    weight = 1.2 * G0_M_S2
    model = np.full(t.size, weight / 0.93)  # the map over-predicts by 1/0.93: the battery gives 93 %
    hover = np.ones(t.size, bool)
    s = hover_thrust_scale(t, model, hover, weight, tau_s=30.0)
    np.testing.assert_allclose(s, 0.93, rtol=1e-12)


def test_a_sagging_battery_is_tracked_causally() -> None:
    """The scale drops 5 % at t = 100 s: before, the estimate ignores what comes after (causal beyond its
    first window); after a few time constants it has followed the drop."""
    t = np.arange(0.0, 300.0, 0.1)
    weight = 10.0
    truth = np.where(t < 100.0, 1.0, 0.95)
    model = weight / truth  # the rotors carry m g while hovering; the map does not know the battery
    s = hover_thrust_scale(t, model, np.ones(t.size, bool), weight, tau_s=10.0)
    assert np.all(np.abs(s[(t > 10.0) & (t < 100.0)] - 1.0) < 1e-12)
    assert abs(s[t > 160.0] - 0.95).max() < 1e-3
    assert np.all(np.diff(s[(t >= 100.0)]) <= 1e-15)  # monotone towards the new level


def test_only_hover_samples_count_and_the_tilt_is_taken_out_by_the_caller() -> None:
    """A banked hover needs T = m g / cos(bank); passing the vertical thrust T cos(bank) gives scale 1."""
    t = np.arange(0.0, 60.0, 0.1)
    weight = 12.0
    bank = np.radians(20.0)
    body_thrust = np.full(t.size, weight / np.cos(bank))
    hover = t > 5.0
    body_thrust[~hover] = 3.0 * weight  # a climb: not a hover sample, must not count
    s = hover_thrust_scale(t, body_thrust * np.cos(bank), hover, weight, tau_s=20.0)
    np.testing.assert_allclose(s[t > 5.0], 1.0, rtol=1e-12)
    assert np.all(hover_thrust_scale(t, body_thrust, np.zeros(t.size, bool), weight, 20.0) == 1.0)


@pytest.mark.parametrize("tau", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_time_constant_is_named(tau: float) -> None:
    with pytest.raises(ValueError, match="tau_s"):
        hover_thrust_scale(np.arange(3.0), np.ones(3), np.ones(3, bool), 1.0, tau)


def test_equivalent_voltage_is_nominal_times_scale() -> None:
    np.testing.assert_allclose(equivalent_voltage_V(np.array([1.0, 0.9]), 11.1), [11.1, 9.99])


def test_a_map_that_falls_with_the_command_falls_back_to_the_square_law() -> None:
    """Thrust that peaks inside the band (what battery sag does to a one-flight fit): the least-squares
    polynomial falls at the top, so the written map is the square law a u^2, a > 0, monotone; data that fall
    everywhere are refused."""
    from identification.thrust.dataset import ThrustDataError
    from identification.thrust.model import FlightData, ModelSpec, fit_physical, is_physical

    rng = np.random.default_rng(1)
    u = rng.uniform(0.3, 0.6, (2000, 4))
    y = (10.0 * u - 12.0 * u**2).sum(axis=1)  # per motor: rises to u = 0.42, falls after
    flight = FlightData("f", 1000.0 + 1000.0 * u, None, np.ones(2000, bool), np.arange(2000) * 0.1, y, 7.0, 0.1)
    spec = ModelSpec(1000.0, 2000.0, 11.1, False, n_rules=2)
    fitted, used = fit_physical([flight], spec, 20, 5.0, "test")
    assert used.features == ("x2",) and used.n_rules == 1
    assert fitted.params.thrust_map.consequents[0][0] > 0.0 and is_physical(fitted.params, [flight], used)
    falling = FlightData("g", 1000.0 + 1000.0 * u, None, np.ones(2000, bool), np.arange(2000) * 0.1, -y, 7.0, 0.1)
    with pytest.raises(ThrustDataError, match="square law"):
        fit_physical([falling], spec, 20, 5.0, "test")
