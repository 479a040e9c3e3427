"""Motor commands rebuilt from ArduCopter's RATE mixer inputs, on DataFlash logs of the project's writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from identification.logs.dataflash_writer import MessageLayout, write_log
from identification.logs.readers import read_log
from identification.quadrotor.rate_commands import reconstruct, with_rebuilt_commands

RATE = MessageLayout("RATE", "Qffffffffffff", "TimeUS,RDes,R,ROut,PDes,P,POut,YDes,Y,YOut,ADes,A,AOut")
#: ArduCopter Quad X mixer factors (AP_MotorsMatrix, normalised to +-0.5): roll, pitch, yaw per motor 1..4
FACTORS = np.array([[-0.5, 0.5, 0.5], [0.5, -0.5, 0.5], [0.5, 0.5, -0.5], [-0.5, -0.5, -0.5]])
MOTORS = {f"SERVO{k}_FUNCTION": 32.0 + k for k in range(1, 5)}  # outputs 1-4: motors 1-4


def _mixer_inputs(t: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (-1..1) and throttle (0..1) as a rate controller swings them: sums of 0.3..8 Hz sines."""
    rng = np.random.default_rng(1)
    out = []
    for amp, base in ((0.15, 0.0), (0.15, 0.0), (0.08, 0.0), (0.06, 0.45)):
        f, ph = rng.uniform(0.3, 8.0, 6), rng.uniform(0, 2 * np.pi, 6)
        out.append(base + amp / 3 * np.sin(2 * np.pi * f * t[:, None] + ph).sum(axis=1))
    return np.column_stack(out)


def _pwm(u: np.ndarray) -> np.ndarray:
    """Motor PWM [us] of the linear Quad X mixer: 1000 + 1000 (throttle + factors . (roll, pitch, yaw))."""
    return 1000.0 + 1000.0 * (u[:, 3:4] + u[:, :3] @ FACTORS.T)


def _log(tmp_path: Path, name: str, related: bool) -> Path:
    t_fast = np.arange(0.0, 30.0, 0.0025)  # RATE at 400 Hz
    t_slow = np.arange(0.0, 30.0, 0.1)  # RCOU at 10 Hz, as the Erle flights
    u = _mixer_inputs(t_fast)
    rate = {"ROut": u[:, 0], "POut": u[:, 1], "YOut": u[:, 2], "AOut": u[:, 3]}
    if related:
        pwm = _pwm(_mixer_inputs(t_slow)) + np.random.default_rng(2).normal(0.0, 2.0, (len(t_slow), 4))
    else:  # outputs that the logged mixer inputs do not drive (a random walk per motor)
        pwm = 1450.0 + np.cumsum(np.random.default_rng(3).normal(0.0, 20.0, (len(t_slow), 4)), axis=0)
    rcou = {f"C{k}": np.round(pwm[:, k - 1]) for k in range(1, 5)}
    return write_log(tmp_path / name, {"RATE": (t_fast, rate), "RCOU": (t_slow, rcou)}, MOTORS, layouts=[RATE])


def test_commands_rebuilt_at_the_rate_controller_rate(tmp_path: Path) -> None:
    log = read_log(_log(tmp_path, "mixer.bin", related=True))
    fit = reconstruct(log)
    assert fit is not None and fit.usable, fit and fit.reason
    assert fit.rate_hz == pytest.approx(400.0) and fit.output_hz == pytest.approx(10.0)
    np.testing.assert_allclose(fit.coef_us[:, 1:4], 1000.0 * FACTORS, atol=15.0)  # the mixer's factors
    np.testing.assert_allclose(fit.coef_us[:, 4], 1000.0, atol=15.0)
    assert all(s["lo"] > 0.9 for s in fit.skill) and max(fit.rmse_us) < 3.0  # noise 2 us, rounding 0.3 us
    rebuilt = with_rebuilt_commands(log, fit)
    m1 = rebuilt.signal("motor_1_pwm_us")
    assert 1 / np.median(np.diff(m1.t_s)) == pytest.approx(400.0)
    truth = _pwm(_mixer_inputs(m1.t_s))[:, 0]
    assert np.sqrt(np.mean((m1.values - truth) ** 2)) < 2.0
    assert rebuilt.has("motor_1_pwm_logged_us") and "rebuilt" in rebuilt.warnings[-1]
    assert not log.has("motor_1_pwm_logged_us")  # the read log is left as it was


def test_unrelated_outputs_are_refused_with_the_reason(tmp_path: Path) -> None:
    fit = reconstruct(read_log(_log(tmp_path, "walk.bin", related=False)))
    assert fit is not None and not fit.usable
    assert "do not predict held-out outputs" in fit.reason and "better than holding the previous output" in fit.reason


def test_no_rate_message_gives_none(tmp_path: Path) -> None:
    t = np.arange(0.0, 5.0, 0.1)
    f = write_log(tmp_path / "rcou.bin", {"RCOU": (t, {f"C{k}": 1500 for k in range(1, 5)})}, MOTORS)
    assert reconstruct(read_log(f)) is None


def test_fill_in_rebuilds_every_log_or_says_why_not(tmp_path: Path) -> None:
    from identification.quadrotor.rate_commands import fill_in

    good = read_log(_log(tmp_path, "mixer.bin", related=True))
    notes: list[str] = []
    logs, hz, why = fill_in([good], 10.0, 50.0, notes)
    assert hz == pytest.approx(400.0) and why == "" and logs[0].has("motor_1_pwm_logged_us")
    assert "rebuilt at 400 Hz" in notes[0]
    bad = read_log(_log(tmp_path, "walk.bin", related=False))
    notes = []
    logs, hz, why = fill_in([good, bad], 10.0, 50.0, notes)  # one log that cannot: none is rebuilt
    assert hz == 10.0 and not notes and not logs[0].has("motor_1_pwm_logged_us")
    assert "walk.bin" in why and "mixer.bin" not in why
