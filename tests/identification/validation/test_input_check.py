"""Logged inputs checked against what the FMU was built for: battery cell count and PWM ranges."""

from __future__ import annotations

import numpy as np
import pytest

from identification.validation.input_check import battery_finding, cells_of, check_inputs, pwm_finding


def test_cell_counts_of_lipo_packs() -> None:
    assert [cells_of(v) for v in (3.7, 7.4, 11.1, 12.6, 14.8, 16.0, 22.2)] == [1, 2, 3, 3, 4, 4, 6]


def test_a_4s_log_against_a_3s_fmu_is_a_finding_and_a_3s_log_is_not() -> None:
    f = battery_finding(np.linspace(15.1, 16.2, 50), 11.1, "the logged voltage")
    assert f is not None and f.input == "battery_voltage_V" and f.check == "battery cells"
    assert "4S" in f.logged and f.expected.startswith("3S") and "15.10..16.20 V" in f.logged
    for sag in (np.linspace(12.4, 10.2, 50), np.linspace(10.55, 10.12, 50)):  # a 3S pack sagging in flight
        assert battery_finding(sag, 11.1, "the logged voltage") is None
    assert battery_finding(np.full(5, np.nan), 11.1, "x") is None  # nothing logged: nothing to say


def test_pwm_outside_the_range_counts_the_scored_samples_only() -> None:
    pwm = np.array([1500.0, 2000.0, 2001.0, 2100.0, 950.0])
    f = pwm_finding("pwm_1_us", pwm, 1000.0, 2000.0, "range", "as logged")
    assert f is not None and f.share == pytest.approx(2 / 5) and "1 above" in f.logged and "1 below" in f.logged
    assert "max 2100" in f.logged and "min 950" in f.logged
    assert pwm_finding("pwm_1_us", pwm[:3], 1000.0, 2000.0, "range", "as logged") is None  # within 1 us
    scored = np.array([True, True, True, False, False])
    inputs = {f"pwm_{k}_us": pwm for k in range(1, 5)}
    params = {"pwm_idle_us": 1000.0, "pwm_full_us": 2000.0, "battery_nominal_V": 11.1}
    assert check_inputs("quadrotor", inputs, {}, params, None, {}, scored) == []
    found = check_inputs("quadrotor", {**inputs, "battery_voltage_V": np.full(5, 16.0)}, {}, params,
                         np.full(5, 16.0), {"battery_voltage_V": "11.1 (--set battery_voltage_V)"}, np.ones(5, bool))
    assert [f.input for f in found] == ["battery_voltage_V", *inputs]  # below idle is a stopped motor: no finding
    assert found[0].fed == "11.1 (--set battery_voltage_V)"
    wing = check_inputs("fixed_wing", {}, {"aileron_rad": (np.array([1500.0, 2050.0]), (1100.0, 1900.0, "ch 1"))},
                        {}, None, {}, np.ones(2, bool))
    assert len(wing) == 1 and wing[0].fed.startswith("the range's end") and wing[0].share == 0.5
