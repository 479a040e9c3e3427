"""Fit metrics against values computed by hand."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from identification.common.metrics import MetricsError, fit_metrics, overall_outcome


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
    from identification.common.metrics import segment_metrics

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


def _replay(skill_target: float, spread: float, seed: int = 3, included: list[bool] | None = None,
            gate: bool = True, rate_hz: float = 50.0, windows: int = WINDOWS, score_it: bool = True):
    """A scored replay of one signal over 60 windows whose pooled skill against persistence is exactly
    ``skill_target`` and whose per-window error ratio (model / persistence, squared) spreads uniformly by
    +-``spread``: the bootstrap interval of the skill is about +-0.85 ``spread`` / sqrt(60) wide."""
    from identification.validation.output_map import SignalMap
    from identification.validation.replay import ReplayResult, score

    rng = np.random.default_rng(seed)
    n = windows * WINDOW_LEN
    init = 10.0 + np.cumsum(rng.normal(size=windows))
    e_pers = rng.normal(size=n)  # measured minus persistence
    ratio2 = rng.uniform(-spread, spread, windows)
    sse = np.add.reduceat(e_pers**2, np.arange(0, n, WINDOW_LEN))
    ratio2 += (1.0 - skill_target) ** 2 - np.sum(ratio2 * sse) / np.sum(sse)  # pooled skill exactly on target
    y = np.repeat(init, WINDOW_LEN) + e_pers
    model = y - np.repeat(np.sqrt(ratio2), WINDOW_LEN) * e_pers
    edges = np.arange(0, n + 1, WINDOW_LEN)
    res = ReplayResult({"path": "m.fmu"}, {"path": "f.bin", "warnings": []}, np.arange(n) * 0.02,
                       {"altitude_m": model}, {"altitude_m": y},
                       [(float(a), float(b)) for a, b in itertools.pairwise(edges)], [], {},
                       (SignalMap("altitude_m", "altitude_m", gate=gate),),
                       included=[True] * windows if included is None else included, options={"rate_hz": rate_hz})
    if score_it:
        score(res, edges, {"altitude_m": init})
    return res


def _summary(res):
    from pathlib import Path

    from identification.validation.workflow import ValidationJob, metrics_document, result_of

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

    from identification.validation.replay import score
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
    from identification.common.metrics import block_starts

    assert block_starts(1, 1).tolist() == [0]
    assert block_starts(7, 1).tolist() == list(range(7))
    assert block_starts(10, 4).tolist() == [0, 4, 8] and block_starts(10, 4).dtype.kind == "i"
    for bad in ((0, 1), (5, 0)):
        with pytest.raises(MetricsError, match=rf"n_samples >= 1 and block_len >= 1, got {bad[0]}, {bad[1]}"):
            block_starts(*bad)


def test_option_problems_are_named_as_command_line_options() -> None:
    from identification.validation.replay import ValidationInputError, check_options

    assert check_options(rate_hz=25.0).rate_hz == 25.0
    with pytest.raises(ValidationInputError) as err:
        check_options(rate_hz=-1.0, window_s=1e9)
    lines = str(err.value).split("; ")
    assert len(lines) == 2 and lines[0].startswith("--rate-hz") and lines[1].startswith("--window-s"), lines


def test_one_step_force_check_verdicts() -> None:
    """The FMU's specific force at each restart against the logged accelerometer, beside the log's mean:
    pass with a margin, tie inside the noise, FAIL when the mean does better; fewer than 2 restarts: none."""
    from identification.logs.flightlog import FlightLog, Signal
    from identification.validation.replay import _one_step

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


# --------------------------------------------------------------------------- edge cases by hand
def test_fit_metrics_degenerate_series() -> None:
    one = fit_metrics(np.array([2.0]), np.array([1.5]))  # one sample: no spread to normalise by
    assert (one.rmse, one.n, one.nrmse, one.r2, one.fit_percent) == (0.5, 1, math.inf, -math.inf, -math.inf)
    flat = fit_metrics(np.full(4, 3.0), np.array([3.0, 3.0, 3.0, 4.0]))
    assert flat.nrmse == math.inf and flat.r2 == -math.inf and flat.theil_u == pytest.approx(0.5 / (3 + 3.2787),
                                                                                               rel=1e-4)
    zero = fit_metrics(np.zeros(3), np.zeros(3))
    assert zero.theil_u == 0.0 and zero.rmse == 0.0
    ints = fit_metrics([1, 2, 3], [1, 2, 4])  # plain lists of integers
    assert ints.rmse == pytest.approx(math.sqrt(1 / 3)) and ints.r2 == pytest.approx(0.5)
    with pytest.raises(MetricsError, match=r"^no sample where both measured and model values are finite$"):
        fit_metrics(np.array([np.nan, 1.0]), np.array([1.0, np.nan]))


def test_skill_and_rmse_edges() -> None:
    import warnings

    from identification.common.metrics import rmse, skill

    assert skill(0.5, 0.5) == 0.0 and skill(0.25, 1.0) == 0.75 and skill(2.0, 1.0) == -1.0
    for model, base in ((1.0, 0.0), (math.inf, 1.0), (1.0, math.inf), (math.nan, 1.0), (0.0, -1.0)):
        assert math.isnan(skill(model, base)), (model, base)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an all-NaN error is NaN, quietly
        assert math.isnan(rmse(np.array([np.nan, 1.0]), np.array([1.0, np.inf])))
    assert rmse([1, 2], [1, 4]) == pytest.approx(math.sqrt(2.0))


def test_window_baselines_and_segment_rmse_by_hand() -> None:
    from identification.common.metrics import segment_rmse, window_baselines

    y = np.array([1.0, 3.0, np.nan, 4.0, np.nan, 7.0, np.nan, np.nan])
    starts = np.array([0, 3, 5, 6])  # segments [1, 3, nan], [4, nan], [7], [nan, nan]
    pers, mean = window_baselines(y, starts, np.array([0.5, 4.5, 6.0, 1.0]))
    assert pers.tolist() == [0.5, 0.5, 0.5, 4.5, 4.5, 6.0, 1.0, 1.0]
    assert mean[:6].tolist() == [2.0, 2.0, 2.0, 4.0, 4.0, 7.0] and np.isnan(mean[6:]).all()
    m = np.array([2.0, 3.0, 0.0, np.nan, 5.0, 4.0, 1.0, 1.0])
    got = segment_rmse(y, m, starts)  # over samples finite in both only
    assert got[0] == pytest.approx(math.sqrt(0.5)) and got[2] == pytest.approx(3.0)
    assert np.isnan(got[1]) and np.isnan(got[3])
    assert segment_rmse([1, 2], [2, 4], np.array([0, 1])).tolist() == [1.0, 2.0]


def test_segment_metrics_checks_and_near_constant_segments() -> None:
    from identification.common.metrics import segment_metrics

    with pytest.raises(MetricsError, match=r"^measured has 3 samples, model 2: they must match$"):
        segment_metrics(np.zeros(3), np.zeros(2), np.array([0]))
    for starts in ([0, 0, 2], [0, 3]):  # repeated start, start beyond the series
        with pytest.raises(MetricsError, match=r"^segment starts must increase strictly and lie inside the series$"):
            segment_metrics(np.zeros(3), np.zeros(3), np.array(starts))
    segment_metrics(np.zeros(3), np.zeros(3), np.array([0, 1, 2]))  # one-sample segments are fine
    # a segment that moves by 1e-4 around 1e6: its spread is below the rounding of the sums -> no R^2
    y = np.array([1e6, 1e6 + 1e-4, 0.0, 1.0, 5.0, 5.0, 0.0, 0.0])
    m = y + np.array([0.0, 0.0, 0.5, 0.0, 1.0, 0.0, 0.0, 0.0])
    near, ok, flat, zero = segment_metrics(y, m, np.array([0, 2, 4, 6]))
    assert near.r2 == -math.inf and near.fit_percent == -math.inf
    assert ok.r2 == pytest.approx(1 - 0.25 / 0.5) and ok.nrmse == pytest.approx(math.sqrt(0.125))
    assert flat.nrmse == math.inf and flat.r2 == -math.inf and zero.theil_u == 0.0
    y[3] = np.nan  # a segment with a NaN takes the exact route
    assert segment_metrics(y, m, np.array([0, 2, 4, 6]))[1] == fit_metrics(y[2:4], m[2:4])


def test_skill_interval_arguments_and_edges() -> None:
    from identification.common.metrics import skill_interval

    rng = np.random.default_rng(2)
    y = rng.normal(size=60)
    m, b, s = y + 0.5 * rng.normal(size=60), y + rng.normal(size=60), np.arange(0, 60, 10)
    for level in (0.5, 0.99):
        assert skill_interval(y, m, b, s, level=level).level == level
    for level in (0.49, 1.0):
        with pytest.raises(MetricsError, match=rf"^level must lie in \[0.5, 1\), got {level}$"):
            skill_interval(y, m, b, s, level=level)
    for n_boot in (10, 100_000):
        assert math.isfinite(skill_interval(y, m, b, s, n_boot=n_boot).lo)
    for n_boot in (9, 100_001):
        with pytest.raises(MetricsError, match=rf"^n_boot must lie in \[10, 100000\], got {n_boot}$"):
            skill_interval(y, m, b, s, n_boot=n_boot)
    with pytest.raises(MetricsError, match=r"^measured, model and baseline have 60, 60, 59 samples: they must match$"):
        skill_interval(y, m, b[:-1], s)
    for bad in ([], [1, 10], [0, 10, 10], [0, 60], [0, 30, 20]):
        with pytest.raises(MetricsError, match=r"^block starts must begin at 0, increase strictly and lie inside"):
            skill_interval(y, m, b, np.array(bad, dtype=int))
    default = skill_interval(y, m, b, s)
    assert default == skill_interval(y, m, b, s, n_boot=2000, seed=0) != skill_interval(y, m, b, s, seed=1)
    assert default.n_blocks == 6 and default.lo < default.skill < default.hi


def test_skill_interval_blocks_left_out_and_degenerate_baselines() -> None:
    from identification.common.metrics import skill_interval

    y = np.arange(40.0)
    m, b = y + 0.1, y + 1.0
    b_nan = b.copy()
    b_nan[10:20] = np.nan  # a block without a finite baseline is dropped, not counted
    res = skill_interval(y, m, b_nan, np.arange(0, 40, 10))
    assert res.n_blocks == 3 and res.skill == pytest.approx(0.9)
    assert res.lo == pytest.approx(0.9) and res.hi == pytest.approx(0.9) and res.outcome == "win"
    one = skill_interval(y, m, b, np.array([0]))
    assert one.skill == pytest.approx(0.9) and math.isnan(one.lo) and math.isnan(one.hi)
    assert (one.level, one.n_blocks, one.outcome) == (0.9, 1, "tie")
    two = skill_interval(y, m, b, np.array([0, 20]))
    assert two.n_blocks == 2 and two.lo == pytest.approx(0.9) and two.outcome == "win"
    exact = skill_interval(y, m, y.copy(), np.arange(0, 40, 10))  # the baseline is exact: nothing to beat
    assert math.isnan(exact.skill) and math.isnan(exact.lo) and math.isnan(exact.hi)
    assert (exact.level, exact.n_blocks) == (0.9, 4)
    empty = skill_interval(y, np.full(40, np.nan), b, np.arange(0, 40, 10))
    assert empty.n_blocks == 0 and math.isnan(empty.skill)
    # baseline error in one block of three: resamples without it have no skill (-inf), and a 90 % interval
    # reaches them (each resample misses it with probability (2/3)^3 = 0.30)
    b_one = y.copy()
    b_one[:10] += 1.0
    sparse = skill_interval(y[:30], m[:30], b_one[:30], np.array([0, 10, 20]))
    assert sparse.lo == -math.inf and sparse.hi == pytest.approx(1 - math.sqrt(0.015), rel=1e-6)  # drawn twice
    first = b.copy()
    first[10:] = y[10:]  # only the first block has a baseline error: every resample must be able to draw it
    assert skill_interval(y, m, first, np.arange(0, 40, 10), level=0.5).hi > -math.inf


def _close(a, b) -> bool:
    return all(x == pytest.approx(y, rel=1e-9) for x, y in zip(a.as_dict().values(), b.as_dict().values(),
                                                                 strict=True))


def test_score_leaves_excluded_windows_out_and_counts_window_verdicts() -> None:
    included = [k % 7 != 3 for k in range(WINDOWS)]  # every 7th window from the 4th excluded
    res = _replay(0.30, 0.40, included=included, gate=False)
    y, model = res.measured["altitude_m"], res.model["altitude_m"]
    for k, inc in enumerate(included):
        sl = slice(k * WINDOW_LEN, (k + 1) * WINDOW_LEN)
        assert np.isnan(res.persistence["altitude_m"][sl]).all() != inc
        if not inc:
            assert res.window_metrics[k] == {} and res.window_scores[k] == {}
            continue
        w = res.window_scores[k]["altitude_m"]
        pers = res.persistence["altitude_m"][sl]
        assert _close(w.fit, fit_metrics(y[sl], model[sl])) and w.gated is False
        assert w.rmse_persistence == pytest.approx(math.sqrt(np.mean((y[sl] - pers) ** 2)))
        assert w.rmse_mean == pytest.approx(np.std(y[sl]))
        assert res.window_metrics[k]["altitude_m"] == w.fit
    verdicts = [w["altitude_m"].verdict for w in res.window_scores if w]
    assert res.window_counts("altitude_m") == {v: verdicts.count(v) for v in ("pass", "FAIL", "tie", "n/a")}
    assert sum(res.window_counts("altitude_m").values()) == sum(included) and res.window_counts("x")["pass"] == 0
    keep = np.repeat(included, WINDOW_LEN)
    s = res.scores["altitude_m"]
    assert res.overall["altitude_m"] == s.fit and _close(s.fit, fit_metrics(y[keep], model[keep])) and not s.gated
    assert s.interval.n_blocks == sum(included)
    assert s.rmse_mean == pytest.approx(math.sqrt(np.mean(
        np.concatenate([(y[k * 50:(k + 1) * 50] - y[k * 50:(k + 1) * 50].mean()) ** 2
                        for k in range(WINDOWS) if included[k]]))))
    assert res.status == "unscored"  # its only signal is not gated


def test_single_window_is_cut_into_time_blocks_for_the_interval() -> None:
    from identification.validation.replay import score

    for rate_hz, blocks in ((50.0, 30), (25.0, 60)):  # 2 s blocks: 100 or 50 samples of 3000
        res = _replay(0.30, 0.40, rate_hz=rate_hz, score_it=False)
        n = WINDOWS * WINDOW_LEN
        res.windows, res.included = [(0.0, n * 0.02)], [True]
        score(res, np.array([0, n]), {"altitude_m": res.measured["altitude_m"][:1]})
        assert res.scores["altitude_m"].interval.n_blocks == blocks


def test_a_model_without_finite_values_is_named() -> None:
    from identification.validation.replay import ValidationInputError, score

    res = _replay(0.30, 0.40, score_it=False)
    res.model["altitude_m"][:] = np.nan
    with pytest.raises(ValidationInputError, match=r"^altitude_m: .*\(no finite FMU value in the scored windows\)$"):
        score(res, np.arange(0, WINDOWS * WINDOW_LEN + 1, WINDOW_LEN), {"altitude_m": np.zeros(WINDOWS)})


def test_bad_options_name_their_source() -> None:
    from fmu_models.config import ConfigError
    from identification.validation.replay import options

    with pytest.raises(ConfigError, match=r"^validate options: 1 problem"):
        options(rate_hz=-1.0)
    with pytest.raises(ConfigError, match=r"^job 3: 1 problem"):
        options("job 3", window_s=-1.0)
    assert options(rate_hz=None, window_s=4.0).rate_hz == 50.0  # None: the default



def test_json_rows_carry_their_names() -> None:
    from identification.validation.replay import HorizonRow, _one_step

    res = _replay(0.30, 0.40)
    row = res.scores["altitude_m"].as_dict()
    assert {"rmse_persistence", "rmse_mean", "skill_persistence", "skill_mean", "verdict", "reason", "gated",
            "skill_persistence_lo", "skill_persistence_hi", "skill_level", "skill_blocks", "skill_outcome",
            "rmse", "theil_u", "r2", "n"} <= set(row)
    assert (row["skill_level"], row["skill_blocks"]) == (0.9, WINDOWS)
    assert row["rmse_mean"] == res.scores["altitude_m"].rmse_mean
    h = HorizonRow(0.5, 1.0, 2.0, 7)
    assert h.as_dict() == {"horizon_s": 0.5, "rmse": 1.0, "rmse_persistence": 2.0, "skill_persistence": 0.5, "n": 7}
    from identification.logs.flightlog import FlightLog, Signal

    t = np.arange(4.0)
    log = FlightLog("f.bin", "csv", {"a": Signal("a", t, np.array([0.0, 1.0, 0.0, 1.0]), "m/s2")}, {})
    two = np.array([[0.1], [0.9], [np.nan], [np.nan]])  # two restarts: enough for a score
    out = _one_step(log, t, two, ["a"])["a"]
    assert out.fit.n == 2 and math.isnan(out.rmse_persistence) and out.gated is False
    worse = _one_step(log, t, np.array([[1.0], [0.0], [1.0], [0.0]]), ["a"])["a"]
    assert worse.verdict == "FAIL" and "force model loses to the log's mean specific force (skill -1.00, 90 % " \
        "interval" in worse.reason


@pytest.mark.parametrize(("outcomes", "verdict"), [
    (["win", "win"], "win"),
    (["win", "lose"], "lose"),  # one lost comparison (a baseline, a held-out flight) is a loss, however many win
    (["lose", "win", "win"], "lose"),
    (["win", "tie"], "tie"),
    (["tie", "lose"], "lose"),
    ([], "tie"),  # nothing scored is no win
])
def test_overall_outcome_any_loss_loses_and_only_all_wins_win(outcomes: list[str], verdict: str) -> None:
    assert overall_outcome(outcomes) == verdict
