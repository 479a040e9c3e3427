"""Skill with a margin: block-bootstrap intervals decide win, tie or lose."""

import numpy as np
import pytest

from identification.common.metrics import MetricsError, block_starts, skill_interval


def _series(rng: np.random.Generator, n: int, model_sd: float, base_sd: float):
    y = rng.standard_normal(n)
    return y, y + model_sd * rng.standard_normal(n), y + base_sd * rng.standard_normal(n)


def test_clear_win_is_a_win_and_clear_loss_a_loss():
    rng = np.random.default_rng(1)
    y, m, b = _series(rng, 4000, 0.5, 1.0)
    starts = block_starts(y.size, 100)
    win = skill_interval(y, m, b, starts)
    assert win.outcome == "win" and win.lo > 0.3 and win.lo <= win.skill <= win.hi
    lose = skill_interval(y, b, m, starts)
    assert lose.outcome == "lose" and lose.hi < 0


def test_small_skill_with_noise_is_a_tie():
    """A model whose skill is +0.02 with a standard error of about 0.05 is a tie, not a win; the same skill
    with little spread across blocks is a win."""
    rng = np.random.default_rng(2)
    n_blocks, per = 20, 50
    y = np.zeros(n_blocks * per)
    e = rng.standard_normal((n_blocks, per))
    e = (e / np.sqrt(np.mean(e * e, axis=1, keepdims=True))).ravel()  # baseline MSE exactly 1 in every block
    starts = block_starts(y.size, per)

    def with_ratio_spread(sd: float):
        g = rng.gamma(1.0 / sd**2, sd**2, n_blocks)  # block MSE ratios, mean 1 after scaling
        ratio = 0.98**2 * g / g.mean()  # pooled skill exactly 1 - 0.98 = 0.02
        return skill_interval(y, y + np.repeat(np.sqrt(ratio), per) * e, y + e, starts)

    noisy = with_ratio_spread(0.45)  # standard error of the skill about 0.45 / sqrt(20) / 2 = 0.05
    assert abs(noisy.skill - 0.02) < 1e-9
    assert noisy.outcome == "tie" and noisy.lo < 0 < noisy.hi and noisy.hi - noisy.lo > 0.08
    steady = with_ratio_spread(0.005)
    assert abs(steady.skill - 0.02) < 1e-9 and steady.outcome == "win"


def test_a_model_the_baseline_beats_loses_even_inside_the_noise():
    """Skill -0.02 with an interval that reaches above zero: the baseline's RMSE is lower on these data, so the
    model is reported as losing; the same RMSE is a tie."""
    rng = np.random.default_rng(2)
    n_blocks, per = 20, 50
    y = np.zeros(n_blocks * per)
    e = rng.standard_normal((n_blocks, per))
    e = (e / np.sqrt(np.mean(e * e, axis=1, keepdims=True))).ravel()
    g = rng.gamma(1.0 / 0.45**2, 0.45**2, n_blocks)
    ratio = 1.02**2 * g / g.mean()  # pooled skill exactly 1 - 1.02 = -0.02
    res = skill_interval(y, y + np.repeat(np.sqrt(ratio), per) * e, y + e, block_starts(y.size, per))
    assert abs(res.skill + 0.02) < 1e-9 and res.lo < 0 < res.hi
    assert res.outcome == "lose"
    equal = skill_interval(y, y + e, y + e, block_starts(y.size, per))  # the baseline itself: no worse
    assert equal.skill == 0.0 and equal.outcome == "tie"
    worse = skill_interval(y, y + 1.002 * e, y + e, block_starts(y.size, per))  # 0.2 % above: beaten
    assert worse.outcome == "lose"


def test_deterministic_for_a_seed_and_checks_inputs():
    rng = np.random.default_rng(3)
    y, m, b = _series(rng, 600, 0.9, 1.0)
    s = block_starts(y.size, 60)
    assert skill_interval(y, m, b, s, seed=7) == skill_interval(y, m, b, s, seed=7)
    with pytest.raises(MetricsError):
        skill_interval(y, m, b[:-1], s)
    with pytest.raises(MetricsError):
        skill_interval(y, m, b, s, n_boot=10**7)
    with pytest.raises(MetricsError):
        skill_interval(y, m, b, np.array([5, 10]))


def test_nothing_to_score_is_not_a_win():
    y = np.ones(100)
    res = skill_interval(y, y + 0.1, y, block_starts(100, 10))  # baseline exact
    assert res.outcome == "tie" and np.isnan(res.skill)


def test_aero_verdicts_follow_the_same_rule() -> None:
    """``identify aero``'s held-out table: an output a rival beats is losing (exit 4), one it only ties is not."""
    from types import SimpleNamespace

    from identification.aero.identify import _baselines

    rng = np.random.default_rng(5)
    n_seg, per = 8, 200
    t = np.linspace(0.0, 4.0, per)
    truth = np.concatenate([np.sin(2.0 * t + k) for k in range(n_seg)])
    good = truth + 0.05 * rng.standard_normal(truth.size)
    flat = np.concatenate([np.full(per, np.sin(2.0 * t + k).mean()) for k in range(n_seg)])  # the segment mean
    y = np.column_stack([truth, truth])
    m = np.column_stack([good, flat + 0.3])  # output 1: worse than the segment mean
    data = [SimpleNamespace(y=y[k * per:(k + 1) * per], dt_s=0.02) for k in range(n_seg)]
    out = _baselines((y, m, np.zeros(len(y))), data, ["roll_rad", "pitch_rad"])  # type: ignore[arg-type]
    assert out["roll_rad"]["loses_to"] == [] and out["roll_rad"]["ties_with"] == []
    assert "segment_mean" in out["pitch_rad"]["loses_to"]
    same = _baselines((y, np.column_stack([flat, flat]), np.zeros(len(y))), data, ["roll_rad", "pitch_rad"])
    assert same["roll_rad"]["loses_to"] == [] and same["roll_rad"]["ties_with"] == ["segment_mean"]
    # what the command makes of it: a loss exits 4, a tie alone exits 0 (named as a tie)
    from identification.aero.identify import AeroResult
    from uavfmu.commands.identify_aero import EXIT_BASELINE_WINS, EXIT_LATE_FAILURE, EXIT_OK, exit_status

    def verdicts(baselines: dict) -> SimpleNamespace:  # the two properties read only the held-out table
        ns = SimpleNamespace(baselines=baselines, failures=[])
        ns.losing_outputs = AeroResult.losing_outputs.fget(ns)  # type: ignore[attr-defined]
        ns.tied_outputs = AeroResult.tied_outputs.fget(ns)  # type: ignore[attr-defined]
        return ns

    lost, tied = verdicts(out), verdicts(same)
    assert lost.losing_outputs == ["pitch_rad"] and exit_status(lost) == EXIT_BASELINE_WINS  # type: ignore[arg-type]
    assert tied.losing_outputs == [] and tied.tied_outputs == ["roll_rad", "pitch_rad"]
    assert exit_status(tied) == EXIT_OK  # type: ignore[arg-type]
    tied.failures = ["plots: disk full"]
    assert exit_status(tied) == EXIT_LATE_FAILURE  # type: ignore[arg-type]
