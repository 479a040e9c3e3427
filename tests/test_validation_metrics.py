"""Fit metrics against values computed by hand."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from identification.metrics import MetricsError, fit_metrics


def test_hand_computed_example() -> None:
    y = np.array([1.0, 2.0, 3.0, 4.0])
    m = np.array([1.0, 2.0, 3.0, 5.0])
    f = fit_metrics(y, m)
    assert f.rmse == pytest.approx(0.5)  # sqrt(1/4)
    assert f.nrmse == pytest.approx(0.5 / 3.0)
    assert f.theil_u == pytest.approx(0.5 / (math.sqrt(7.5) + math.sqrt(39 / 4)))
    assert f.r2 == pytest.approx(1 - 1 / 5.0)  # SS_res 1, SS_tot 5
    assert f.fit_percent == pytest.approx(100 * (1 - 1 / math.sqrt(5)))
    assert f.max_error == 1.0 and f.n == 4


def test_perfect_fit_and_nan_dropping() -> None:
    y = np.array([0.0, 1.0, np.nan, 2.0])
    f = fit_metrics(y, np.array([0.0, 1.0, 5.0, 2.0]))
    assert f.rmse == 0.0 and f.theil_u == 0.0 and f.r2 == 1.0 and f.fit_percent == 100.0 and f.n == 3


def test_mismatched_lengths_are_an_error() -> None:
    with pytest.raises(MetricsError, match="3 samples, model 2"):
        fit_metrics(np.zeros(3), np.zeros(2))


def test_segment_metrics_equal_fit_metrics_per_segment() -> None:
    from identification.metrics import segment_metrics

    rng = np.random.default_rng(4)
    y = np.cumsum(rng.normal(size=503))
    m = y + rng.normal(0, 0.3, size=503)
    m[100] = np.nan  # a segment with a NaN falls back to the exact per-segment path
    starts = np.array([0, 50, 97, 260, 500])
    got = segment_metrics(y, m, starts)
    ends = [*starts[1:], 503]
    for s, e, g in zip(starts, ends, got, strict=True):
        want = fit_metrics(y[s:e], m[s:e])
        for field in ("rmse", "nrmse", "theil_u", "fit_percent", "r2", "max_error"):
            assert getattr(g, field) == pytest.approx(getattr(want, field), rel=1e-9, abs=1e-12), (s, field)
        assert g.n == want.n


# --------------------------------------------------------------------------- verdicts with a margin
WINDOWS, WINDOW_LEN = 60, 50


def _replay(skill_target: float, spread: float, seed: int = 3):
    """A scored replay of one signal over 60 windows whose pooled skill against persistence is exactly
    ``skill_target`` and whose per-window error ratio (model / persistence, squared) spreads uniformly by
    +-``spread``: the bootstrap interval of the skill is about +-0.85 ``spread`` / sqrt(60) wide."""
    from identification.output_map import SignalMap
    from identification.validation import ReplayResult, score

    rng = np.random.default_rng(seed)
    n = WINDOWS * WINDOW_LEN
    init = 10.0 + np.cumsum(rng.normal(size=WINDOWS))
    e_pers = rng.normal(size=n)  # measured minus persistence
    ratio2 = rng.uniform(-spread, spread, WINDOWS)
    sse = np.add.reduceat(e_pers**2, np.arange(0, n, WINDOW_LEN))
    ratio2 += (1.0 - skill_target) ** 2 - np.sum(ratio2 * sse) / np.sum(sse)  # pooled skill exactly on target
    y = np.repeat(init, WINDOW_LEN) + e_pers
    model = y - np.repeat(np.sqrt(ratio2), WINDOW_LEN) * e_pers
    edges = np.arange(0, n + 1, WINDOW_LEN)
    res = ReplayResult({"path": "m.fmu"}, {"path": "f.bin", "warnings": []}, np.arange(n) * 0.02,
                       {"altitude_m": model}, {"altitude_m": y},
                       [(float(a), float(b)) for a, b in itertools.pairwise(edges)], [], {},
                       (SignalMap("altitude_m", "altitude_m"),), included=[True] * WINDOWS,
                       options={"rate_hz": 50.0})
    score(res, edges, {"altitude_m": init})
    return res


def _summary(res):
    from pathlib import Path

    from identification.validation_workflow import ValidationJob, metrics_document, result_of

    out = result_of(res, ValidationJob(Path("m.fmu"), Path("f.bin")))
    return out, metrics_document(res, out)


def test_a_skill_of_two_percent_plus_minus_five_is_a_tie_not_a_pass() -> None:
    """+0.02 +- 0.05 against persistence: a difference that noise makes. The point rule alone would pass it;
    the verdict is a tie in the score, the console, metrics.json and the exit status."""
    from uavfmu.commands.validate import EXIT_TIE, exit_status

    res = _replay(0.02, 0.80)
    s = res.scores["altitude_m"]
    assert s.skill_persistence == pytest.approx(0.02, abs=1e-9)
    half = (s.interval.hi - s.interval.lo) / 2
    assert 0.03 < half < 0.08 and s.interval.lo < 0 < s.interval.hi  # the case the issue names
    assert s.fit.theil_u < 0.3  # accurate enough: only the margin decides
    assert res.maps[0].judge(s.fit, s.rmse_persistence, s.rmse_mean)[0] == "pass"  # point rule, no interval
    assert s.verdict == "tie" and "with confidence" in s.reason
    assert res.status == "tie" and res.ties == ["altitude_m"] and not res.failed
    out, doc = _summary(res)
    assert out.status == doc["status"] == "tie"
    assert doc["signals"]["altitude_m"]["skill_outcome"] == "tie"
    sig = doc["signals"]["altitude_m"]
    assert sig["skill_persistence_lo"] < 0 < sig["skill_persistence_hi"]
    assert out.lines()[0].endswith("TIE (altitude_m not better than persistence with confidence; nothing fails)")
    assert exit_status([out.status]) == EXIT_TIE != 0


def test_a_clear_margin_passes_and_a_loss_fails() -> None:
    from uavfmu.commands.validate import EXIT_FAIL, EXIT_PASS, exit_status

    win = _replay(0.30, 0.40)
    assert win.scores["altitude_m"].interval.lo > 0 and win.scores["altitude_m"].verdict == "pass"
    assert win.status == "pass" and exit_status([win.status]) == EXIT_PASS
    lose = _replay(-0.02, 0.80)
    assert lose.scores["altitude_m"].verdict == "FAIL" and lose.status == "fail"
    assert exit_status([lose.status, win.status]) == EXIT_FAIL


def test_a_run_with_nothing_scored_is_not_a_pass() -> None:
    """Every gated signal n/a (it never moved beyond its tolerance): the run proved nothing."""
    from dataclasses import replace

    from identification.validation import score
    from uavfmu.commands.validate import EXIT_TIE, exit_status

    res = _replay(0.30, 0.40)
    res.maps = (replace(res.maps[0], max_rmse=1e6),)  # every error within tolerance: n/a
    res.scores, res.overall = {}, {}
    edges = np.arange(0, WINDOWS * WINDOW_LEN + 1, WINDOW_LEN)
    score(res, edges, {"altitude_m": res.measured["altitude_m"][edges[:-1]]})
    assert res.scores["altitude_m"].verdict == "n/a"
    out, doc = _summary(res)
    assert res.status == out.status == doc["status"] == "unscored"
    assert "NOT SCORED" in out.lines()[0] and exit_status([out.status]) == EXIT_TIE


def test_block_starts_by_hand() -> None:
    from identification.metrics import block_starts

    assert block_starts(1, 1).tolist() == [0]
    assert block_starts(7, 1).tolist() == list(range(7))
    assert block_starts(10, 4).tolist() == [0, 4, 8] and block_starts(10, 4).dtype.kind == "i"
    for bad in ((0, 1), (5, 0)):
        with pytest.raises(MetricsError, match=rf"n_samples >= 1 and block_len >= 1, got {bad[0]}, {bad[1]}"):
            block_starts(*bad)


def test_option_problems_are_named_as_command_line_options() -> None:
    from identification.validation import ValidationInputError, check_options

    assert check_options(rate_hz=25.0).rate_hz == 25.0
    with pytest.raises(ValidationInputError) as err:
        check_options(rate_hz=-1.0, window_s=1e9)
    lines = str(err.value).split("; ")
    assert len(lines) == 2 and lines[0].startswith("--rate-hz") and lines[1].startswith("--window-s"), lines


def test_one_step_force_check_verdicts() -> None:
    """The FMU's specific force at each restart against the logged accelerometer, beside the log's mean:
    pass with a margin, tie inside the noise, FAIL when the mean does better; fewer than 2 restarts: none."""
    from identification.flightlog import FlightLog, Signal
    from identification.validation import _one_step

    rng = np.random.default_rng(5)
    t = np.arange(200) * 0.5
    az = -9.8 + np.sin(t / 3.0) + 0.05 * rng.normal(size=t.size)
    log = FlightLog("f.bin", "csv", {"accel_body_z_m_s2": Signal("accel_body_z_m_s2", t, az, "m/s2")}, {})
    good = (az + 0.1 * rng.normal(size=t.size))[:, None]
    out = _one_step(log, t, good, ["accel_body_z_m_s2"])["accel_body_z_m_s2"]
    assert out.verdict == "pass" and out.interval.lo > 0 and not out.gated
    assert out.rmse_mean == pytest.approx(np.std(az), rel=1e-9) and out.fit.n == t.size
    assert "beats the log's mean specific force" in out.reason and "over 200 restarts" in out.reason
    mean = np.full((t.size, 1), np.mean(az))
    d = az - np.mean(az)
    c2 = rng.uniform(0.0, 1.9, t.size)
    c2 *= 0.98 * np.sum(d**2) / np.sum(c2 * d**2)  # pooled skill 1 - sqrt(0.98) = +0.01, widely spread
    tie = _one_step(log, t, (az - np.sqrt(c2) * d)[:, None], ["accel_body_z_m_s2"])["accel_body_z_m_s2"]
    assert tie.interval.skill == pytest.approx(1 - math.sqrt(0.98)) and tie.interval.lo < 0 < tie.interval.hi
    assert tie.verdict == "tie" and "no better with confidence" in tie.reason
    bad = _one_step(log, t, mean - (az[:, None] - np.mean(az)), ["accel_body_z_m_s2"])["accel_body_z_m_s2"]
    assert bad.verdict == "FAIL" and "loses to" in bad.reason
    few = np.full((t.size, 1), np.nan)
    few[0] = -9.8
    assert _one_step(log, t, few, ["accel_body_z_m_s2"]) == {}
