"""The model discrepancy of ``validate --mc``: learned per signal and horizon from replays, stored in the
parameter file beside the covariance, drawn back with the stated coverage, and what brings a wrong model's
bands back to their nominal level on a flight it was not learned on."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from fmu_models.common.errors import ParameterError
from fmu_models.common.params import discrepancy_of
from identification.validation.discrepancy import (
    LEVELS,
    horizons_s,
    learn,
    points,
    read_discrepancy,
    scale_carries,
    scale_of,
    write_discrepancy,
)
from identification.validation.mc_bands import MIXTURE_POINTS, mixture_band
from identification.validation.output_map import SignalMap
from tests.identification.validation.test_mc_bands import (  # noqa: F401 - wing, cluster: fixtures
    IDENTIFIED,
    NAMES,
    _job,
    cluster,
    identified,
    wing,
)
from uavfmu.commands.validate import EXIT_BAND, exit_status

Z95 = 1.6448536269514722  #: standard normal 95 % quantile


def _replay(seed: int, sigma_per_s: float = 1.0, window_s: float = 2.0, n_windows: int = 200,
            rate_hz: float = 50.0) -> SimpleNamespace:
    """A replay stand-in: residual logged - FMU ~ N(0, (sigma h)^2), h the time since the window restart."""
    rng = np.random.default_rng(seed)
    step = round(window_s * rate_hz)
    t = np.arange(1, n_windows * step + 1) / rate_hz
    starts = np.arange(n_windows) * window_s
    h = t - starts[np.clip(np.searchsorted(starts, t, side="left") - 1, 0, None)]
    model = np.zeros(t.size)
    y = sigma_per_s * h * rng.standard_normal(t.size)
    return SimpleNamespace(t_s=t, windows=[(a, a + window_s) for a in starts],
                           maps=(SignalMap("roll_rad", "roll_rad"),), measured={"roll_rad": y},
                           model={"roll_rad": model}, options={"window_s": window_s, "rate_hz": rate_hz}), h


def test_horizon_restarts_at_each_window_and_the_end_sample_belongs_to_its_window() -> None:
    res, h = _replay(0, n_windows=3)
    np.testing.assert_allclose(horizons_s(res), h)
    assert horizons_s(res)[99] == pytest.approx(2.0) and horizons_s(res)[100] == pytest.approx(0.02)


def _band(disc: object, res: SimpleNamespace, h: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The 90 % band of the discrepancy alone on ``res`` (validate --mc's, with the parameter draws left out)."""
    s = disc.signals["roll_rad"]  # type: ignore[attr-defined]
    h = horizons_s(res) if h is None else h
    pts = points(disc.levels, s, h, MIXTURE_POINTS, scale_of(res, "roll_rad", s))  # type: ignore[attr-defined]
    return mixture_band(np.zeros((1, h.size)), pts, 0.0)


def test_learned_quantiles_follow_the_growth_with_horizon_and_draws_cover_ninety_percent() -> None:
    res, _ = _replay(1)
    disc = learn([res], ["synthetic"])
    s = disc.signals["roll_rad"]
    i5, i95 = LEVELS.index(0.05), LEVELS.index(0.95)
    for (a, b), row in zip(zip(s.horizon_edges_s[:-1], s.horizon_edges_s[1:], strict=True), s.quantiles,
                           strict=True):
        rms_h = math.sqrt((b**3 - a**3) / (3 * (b - a)))  # sigma h mixed over the bin: a scale mixture of normals
        assert row[i95] == pytest.approx(-row[i5], abs=0.15 * rms_h + 0.01)  # ~3 sampling sd of the difference
        assert 0.8 * Z95 * a <= row[i95] <= 1.2 * Z95 * rms_h + 0.01
    assert sum(s.samples) == res.t_s.size
    # fresh residuals of the same process fall inside the 5-95 % of the draws about 90 % of the time
    new, _ = _replay(2)
    lo, hi = _band(disc, new)
    inside = (new.measured["roll_rad"] >= lo) & (new.measured["roll_rad"] <= hi)
    assert 0.87 <= inside.mean() <= 0.93
    # a horizon beyond the learned ones takes the last bin, not an extrapolation
    far = points(disc.levels, s, np.array([50.0]), 2000, np.ones(1))
    assert np.abs(far).max() <= max(abs(s.quantiles[-1][0]), s.quantiles[-1][-1]) + 1e-12
    assert np.abs(far).max() == pytest.approx(max(abs(s.quantiles[-1][0]), s.quantiles[-1][-1]))


def test_the_parameter_file_stores_it_beside_the_covariance_and_names_each_problem(tmp_path: Path) -> None:
    res, _ = _replay(5, n_windows=20)
    disc = learn([res], ["synthetic"])
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"uncertainty": identified().model_dump(), "quadrotor": {"mass_kg": 1.2}}))
    write_discrepancy(params, disc)
    data = json.loads(params.read_text())
    assert set(data) == {"uncertainty", "quadrotor", "discrepancy"} and data["quadrotor"] == {"mass_kg": 1.2}
    assert read_discrepancy(params) == disc
    bad = json.loads(params.read_text())
    bad["discrepancy"]["signals"]["roll_rad"]["quantiles"][0] = bad["discrepancy"]["signals"]["roll_rad"][
        "quantiles"][0][::-1]
    bad["discrepancy"]["levels"][0] = 1.5
    with pytest.raises(ParameterError, match=r"p\.json: 2 problem") as err:
        discrepancy_of(bad, str(params))
    assert "discrepancy: field levels.0 = 1.5" in str(err.value) and "a quantile row decreases" in str(err.value)
    assert read_discrepancy(None) is None and discrepancy_of({"uncertainty": {}}, "x") is None


def test_a_band_far_from_its_nominal_coverage_is_exit_4_unless_something_fails() -> None:
    assert exit_status(["band"]) == EXIT_BAND == 4
    assert exit_status(["band", "fail"]) == 1 and exit_status(["band", "pass"]) == 4
    assert exit_status(["pass"]) == 0 and exit_status(["tie"]) == 3


def test_a_learned_discrepancy_brings_a_wrong_models_bands_back_to_their_level(
    fixed_wing_fmu: Path, wing: dict[str, Path], tmp_path: Path, cluster: Any  # noqa: F811 - the fixtures
) -> None:
    """Derivatives 30 % off with the right model's confidence: the parameter bands miss the log (status band,
    exit 4). The same wrong FMU's discrepancy learned on another flight (other seed and manoeuvres) brings the
    held-out flight's bands to about their nominal 90 %."""
    from identification.flights import synthetic
    from identification.validation.workflow import learn_discrepancy, validate_mc

    wrong = identified(scale=1.3)
    t, sig = synthetic.fixed_wing_flight(seconds=40.0, rate_hz=50.0, noise=True, seed=7)
    other = synthetic.write_csv_log(tmp_path / "other.csv", t, sig)
    job = _job(fixed_wing_fmu, wing, None)
    learned = learn_discrepancy(job.__class__(fixed_wing_fmu, other, job.options, mapping=job.mapping,
                                              start_values=dict(zip(NAMES, wrong.mean, strict=True))), [other])
    without = validate_mc(job, wrong, 40, seed=3, executor=cluster)
    with_d = validate_mc(job, wrong, 40, seed=3, executor=cluster, discrepancy=learned.discrepancy)
    cov0 = {s: v["band_coverage"] for s, v in without.signals.items()}
    cov1 = {s: v["band_coverage"] for s, v in with_d.signals.items()}
    print({s: (round(cov0[s], 3), round(cov1[s], 3)) for s in cov0})
    assert without.status == "band" and "BANDS MISCALIBRATED" in without.lines()[0]
    assert np.mean([cov1[s] for s in IDENTIFIED]) > np.mean([cov0[s] for s in IDENTIFIED]) + 0.2
    assert all(0.8 <= cov1[s] <= 0.98 for s in IDENTIFIED), cov1
    # every band at its level, the altitude's too (with the window starts' velocity taken from the GPS, its band
    # covered everything: a finding, status band; read from the specific force it is at its level)
    assert all(0.8 <= c <= 0.98 for c in cov1.values()), cov1
    assert all(v["band_verdict"] == "consistent" for v in with_d.signals.values())
    assert with_d.status != "band"
    assert with_d.replay.bands.info["discrepancy"]["signals"] == list(learned.discrepancy.signals)
    assert with_d.replay.bands.info["discrepancy"]["same_windows"]  # learned with the replay's windows and rate
    assert learned.discrepancy.start_velocity == "force" and with_d.replay.bands.info["discrepancy"]["same_starts"]
    assert not any("discrepancy was learned with" in line for line in with_d.lines())
    from identification.validation.report import validation_page

    page = validation_page(with_d.replay)  # the report: the band, its nominal level, the coverage achieved
    assert "Nominal level 90 %" in page and "model discrepancy learned from 1 replay(s)" in page
    assert "5-95 % band coverage" in page and "BANDS MISCALIBRATED" not in page
    assert "BANDS MISCALIBRATED" in validation_page(without.replay)


def test_the_scale_follows_the_models_own_departure_and_narrows_the_band_where_it_holds_still() -> None:
    """Residual = 0.3 x how far the model moved since the restart x N(0, 1) (plus a little noise): half the
    windows swing, half hold still. The scaled quantiles cover fresh residuals at about 90 % with a band far
    narrower in the quiet windows than in the swinging ones."""
    def replay(seed: int) -> SimpleNamespace:
        res, h = _replay(seed, n_windows=200)
        rng = np.random.default_rng(seed + 100)
        swing = np.repeat(np.arange(200) % 2 == 0, 100)
        model = np.where(swing, 2.0 * h, 0.0)
        res.model["roll_rad"] = model
        res.measured["roll_rad"] = model + 0.3 * model * rng.standard_normal(h.size) + 0.01 * rng.standard_normal(
            h.size)
        res.swing = swing
        return res

    disc = learn([replay(11)], ["synthetic"])
    s = disc.signals["roll_rad"]
    assert s.scale_floor is not None and s.scale_floor > 0.0
    new = replay(12)
    lo, hi = _band(disc, new)
    r = new.measured["roll_rad"] - new.model["roll_rad"]
    assert 0.86 <= float(((r >= lo) & (r <= hi)).mean()) <= 0.97
    width = hi - lo
    assert width[~new.swing].mean() < 0.5 * width[new.swing].mean()


def test_the_scale_is_held_where_a_replay_moves_further_than_any_learning_one() -> None:
    """Learned where the model departs by up to 4 rad from its restart (residual 0.3 x (departure + 1)), the band is
    used on a replay departing five times further whose error stays at the learned size: the scale is held at
    the learning residuals' 99th-percentile scale, so the band there keeps its level (89 % of those samples)
    instead of growing with the departure (carried linearly: 99 %, 2.6 times as wide); below that scale nothing
    changes."""
    def replay(seed: int, rate: float) -> SimpleNamespace:
        res, h = _replay(seed, n_windows=200)
        rng = np.random.default_rng(seed + 300)
        swing = np.repeat(np.arange(200) % 2 == 0, 100)
        model = np.where(swing, rate * h, 0.0)
        res.model["roll_rad"] = model
        # 0.3 x (departure + 1) up to the learning's largest: the floor is the departure's mean, 1 rad
        err = 0.3 * (np.minimum(model, 4.0) + 1.0) * rng.standard_normal(h.size)
        res.measured["roll_rad"] = model + err
        res.swing = swing
        return res

    learning = replay(41, 2.0)
    disc = learn([learning], ["synthetic"])
    s = disc.signals["roll_rad"]  # the model starts at 0: its departure is its magnitude
    assert s.scale_by in ("departure", "magnitude") and s.scale_floor is not None and s.scale_max is not None
    raw = scale_of(learning, "roll_rad", s.model_copy(update={"scale_max": None}))
    assert np.quantile(raw, 0.98) <= s.scale_max <= raw.max()
    far = replay(42, 10.0)
    beyond = scale_of(far, "roll_rad", s.model_copy(update={"scale_max": None})) > s.scale_max
    assert beyond.mean() > 0.3  # most of the swinging samples lie past the learned scale
    lo, hi = _band(disc, far)
    r = far.measured["roll_rad"] - far.model["roll_rad"]
    assert 0.85 <= float(((r >= lo) & (r <= hi))[beyond].mean()) <= 0.97
    unheld = disc.model_copy(update={"signals": {"roll_rad": s.model_copy(update={"scale_max": None})}})
    lo1, hi1 = _band(unheld, far)
    assert float(((r >= lo1) & (r <= hi1))[beyond].mean()) > 0.98  # the linear extrapolation: far too wide
    assert (hi1 - lo1)[beyond].mean() > 2.0 * (hi - lo)[beyond].mean()
    np.testing.assert_allclose((hi - lo)[~beyond], (hi1 - lo1)[~beyond])
    with pytest.raises(ValueError, match="scale_max"):
        s.model_validate({**s.model_dump(), "scale_max": 0.5 * s.scale_floor})
    with pytest.raises(ValueError, match="scale_max"):
        s.model_validate({**s.model_dump(), "scale_floor": None, "scale_max": 1.0})


def test_a_scale_is_kept_only_where_it_beats_the_unscaled_band_on_every_replay_left_out() -> None:
    """Two learning replays whose residual follows the model's departure: the scaled form is kept (learned on one,
    it scores better on the other both ways). One of them replaced by a replay whose residual is largest where
    the model holds still: the departure's scale does not carry from one to the other, and the band is
    unscaled."""
    def replay(seed: int, follows: bool) -> SimpleNamespace:
        res, h = _replay(seed, n_windows=200)
        rng = np.random.default_rng(seed + 100)
        swing = np.repeat(np.arange(200) % 2 == 0, 100)
        model = np.where(swing, 2.0 * h, 0.0)
        res.model["roll_rad"] = model
        size = 0.3 * model if follows else np.where(swing, 0.02, 0.6)
        res.measured["roll_rad"] = model + size * rng.standard_normal(h.size) + 0.01 * rng.standard_normal(h.size)
        return res

    pair = [replay(71, True), replay(72, True)]
    both = learn(pair, ["a", "b"]).signals["roll_rad"]
    assert both.scale_floor is not None and both.scale_by == "departure"
    assert learn(pair, ["a", "b"], scaled=False).signals["roll_rad"].scale_floor is None  # the study switch
    mixed = [replay(73, True), replay(74, False)]
    assert learn(mixed, ["a", "b"]).signals["roll_rad"].scale_floor is None
    assert learn(mixed[:1], ["a"]).signals["roll_rad"].scale_floor is not None  # one replay: the narrowest


def test_a_scale_needs_more_winning_windows_than_chance_gives() -> None:
    """The sign test over the windows left out: 12 of 14 windows won is evidence at 5 % over three forms tried
    (one-sided p 0.0065), 11 of 14 is not (0.029); windows with no scored sample do not count. Two learning
    replays of two windows each whose residual follows the model's departure: the scale wins everywhere, but four
    windows cannot show it (p 1/16), and the band is unscaled; with 200 windows each it is kept (above)."""
    base = np.ones(14)
    assert scale_carries(np.r_[np.zeros(12), 2.0, 2.0], base, forms=3)
    assert not scale_carries(np.r_[np.zeros(11), 2.0, 2.0, 2.0], base, forms=3)
    assert scale_carries(np.r_[np.zeros(11), 2.0, 2.0, 2.0], base, forms=1)  # p 0.029 < 0.05 with one form
    # windows with no scored sample drop out: 11 of 11 won (p 0.0005)
    assert scale_carries(np.r_[np.zeros(11), np.nan, np.nan, 2.0], np.r_[np.ones(11), np.nan, 1.0, np.nan], forms=3)
    assert not scale_carries(np.zeros(0), np.zeros(0), forms=3)

    def replay(seed: int, windows: int) -> SimpleNamespace:
        res, h = _replay(seed, n_windows=windows)
        rng = np.random.default_rng(seed + 100)
        swing = np.repeat(np.arange(windows) % 2 == 0, 100)
        model = np.where(swing, 2.0 * h, 0.0)
        res.model["roll_rad"] = model
        res.measured["roll_rad"] = model + 0.3 * model * rng.standard_normal(h.size) + 0.01 * rng.standard_normal(
            h.size)
        return res

    few = [replay(81, 2), replay(82, 2)]
    assert learn(few, ["a", "b"]).signals["roll_rad"].scale_floor is None


def test_the_band_is_symmetric_so_a_drift_of_the_other_sign_on_a_new_flight_stays_covered() -> None:
    """The learning flight drifts one way (residual +|N(0, 1)| h), the new flight the other way: the quantiles
    are antisymmetric and the band covers the new flight at about its level (a band with the learning flight's
    sign would cover almost nothing of it)."""
    res, _ = _replay(21)
    res.measured["roll_rad"] = np.abs(res.measured["roll_rad"])
    disc = learn([res], ["synthetic"])
    for row in disc.signals["roll_rad"].quantiles:
        np.testing.assert_allclose(row, -np.asarray(row[::-1]), atol=1e-12)
    new, _ = _replay(22)
    new.measured["roll_rad"] = -np.abs(new.measured["roll_rad"])
    lo, hi = _band(disc, new)
    y = new.measured["roll_rad"]
    assert 0.85 <= float(((y >= lo) & (y <= hi)).mean()) <= 0.97


def test_a_lagging_model_is_scaled_by_its_slope_and_its_band_narrows_where_the_output_holds_still() -> None:
    """The log lags the model by 40 ms: the residual is -0.04 s x dFMU/dt. Half the windows oscillate, half hold
    still; the learned form is the slope's, and the band is far narrower where the output holds still."""
    def replay(seed: int) -> SimpleNamespace:
        res, _ = _replay(seed, n_windows=200)
        rng = np.random.default_rng(seed + 200)
        amp = np.repeat(np.where(np.arange(200) % 2 == 0, rng.uniform(0.5, 1.5, 200), 0.0), 100)
        t = res.t_s
        res.model["roll_rad"] = amp * np.sin(2 * math.pi * 1.3 * t)
        res.measured["roll_rad"] = amp * np.sin(2 * math.pi * 1.3 * (t - 0.04)) + 0.002 * rng.standard_normal(t.size)
        res.still = amp == 0.0
        return res

    disc = learn([replay(31)], ["synthetic"])
    assert disc.signals["roll_rad"].scale_by == "slope" and disc.signals["roll_rad"].scale_floor is not None
    new = replay(32)
    lo, hi = _band(disc, new)
    r = new.measured["roll_rad"] - new.model["roll_rad"]
    assert 0.85 <= float(((r >= lo) & (r <= hi)).mean()) <= 0.98
    assert (hi - lo)[new.still].mean() < 0.5 * (hi - lo)[~new.still].mean()


def test_an_angle_is_inside_its_band_modulo_two_pi() -> None:
    from identification.validation.mc_bands import inside_band

    y, lo, hi = np.array([-3.1, 3.2, 0.0]), np.array([3.0, 3.0, 3.0]), np.array([3.3, 3.3, 3.3])
    assert inside_band(y, lo, hi, wrap=True).tolist() == [True, True, False]
    assert inside_band(y, lo, hi).tolist() == [False, True, False]
    assert inside_band(y, lo - 3.2, hi + 3.2, wrap=True).all()  # 2 pi wide or more: every angle


def test_the_band_factor_brings_the_learning_replays_combined_band_to_its_level() -> None:
    """Parameter draws twice as wide as the residuals (a spread counted on top of residuals that carry it),
    convolved with the discrepancy: the band is sqrt(1 + 2^2) times too wide and the factor about 1/sqrt(5);
    draws half as wide: 1/sqrt(1.25). Either way the calibrated band covers 90 % of the learning samples, and
    the same band is what validate's Monte Carlo draws (mixture_band)."""
    from identification.validation.discrepancy import points, scale_of
    from identification.validation.mc_bands import MIXTURE_POINTS, calibrate, mixture_band

    res, _ = _replay(41, sigma_per_s=1.0)
    disc = learn([res], ["synthetic"])
    rng = np.random.default_rng(42)
    h = horizons_s(res)
    r = res.measured["roll_rad"] - res.model["roll_rad"]
    for spread in (2.0, 0.5):
        devs = spread * h * rng.standard_normal((40, h.size))  # residual sd is 1 x h
        s = calibrate(disc, [(res, {"roll_rad": devs})]).signals["roll_rad"]
        assert s.parameter_weight == 1.0  # one learning replay: nothing to leave out, the draws stay in
        assert s.band_factor == pytest.approx(1.0 / math.sqrt(1.0 + spread**2), rel=0.1)
        pts = points(disc.levels, s, h, MIXTURE_POINTS // 40, scale_of(res, "roll_rad", s))
        lo, hi = mixture_band(devs, pts, 1.0, s.band_factor)
        assert float(((r >= lo) & (r <= hi)).mean()) == pytest.approx(0.90, abs=0.01)
    assert disc.signals["roll_rad"].band_factor is None  # calibrate returns a copy


def test_the_discrepancy_alone_reproduces_its_stored_quantiles_and_draws_alone_their_spread() -> None:
    """The band is computed, not drawn: weight 0 gives the stored 5-95 % quantiles per horizon bin to
    interpolation; a discrepancy of zero gives the draws' own 5-95 % (the mixture is the draws)."""
    from identification.validation.discrepancy import points, scale_of
    from identification.validation.mc_bands import MIXTURE_POINTS, mixture_band

    res, _ = _replay(43, sigma_per_s=1.0)
    disc = learn([res], ["synthetic"])
    s, h = disc.signals["roll_rad"], horizons_s(res)
    pts = points(disc.levels, s, h, MIXTURE_POINTS, scale_of(res, "roll_rad", s))
    lo, hi = mixture_band(np.zeros((19, h.size)), pts, 0.0)
    q = np.asarray(s.quantiles)[np.clip(np.searchsorted(s.horizon_edges_s, h, side="right") - 1, 0, None)]
    np.testing.assert_allclose(lo, q[:, LEVELS.index(0.05)], rtol=0.02, atol=1e-3)
    np.testing.assert_allclose(hi, q[:, LEVELS.index(0.95)], rtol=0.02, atol=1e-3)
    devs = np.random.default_rng(44).standard_normal((400, 50))
    lo, hi = mixture_band(devs, np.zeros((3, 50)), 1.0)
    np.testing.assert_allclose(lo, np.quantile(devs, 0.05, axis=0, method="hazen"), atol=1e-12)
    np.testing.assert_allclose(hi, np.quantile(devs, 0.95, axis=0, method="hazen"), atol=1e-12)
    # a draw that stopped after sample 30 is left out there, not the sample; a sample no draw reached is NaN
    devs[0, 30:] = np.nan
    devs[:, 49] = np.nan
    lo, hi = mixture_band(devs, np.zeros((1, 50)), 1.0)
    np.testing.assert_allclose(hi[30:49], np.quantile(devs[1:, 30:49], 0.95, axis=0, method="hazen"), atol=1e-12)
    np.testing.assert_allclose(lo[:30], np.quantile(devs[:, :30], 0.05, axis=0, method="hazen"), atol=1e-12)
    assert np.isnan(lo[49]) and np.isnan(hi[49])


def test_the_parameter_draws_leave_the_band_where_they_do_not_follow_the_error() -> None:
    """Three learning replays whose residual is white noise unrelated to the parameter draws, which swing wide
    in half the windows: the draws only widen the band, and the weight chosen on replays left out is 0. When
    the residual is the draws' own deviation (the model's error is the parameters'), the weight stays 1."""
    from identification.validation.mc_bands import calibrate

    def replay(seed: int, follows: bool) -> tuple[SimpleNamespace, np.ndarray]:
        res, h = _replay(seed, n_windows=60)
        rng = np.random.default_rng(seed + 300)
        swing = np.repeat(np.arange(60) % 2 == 0, 100) * 3.0 + 0.1
        devs = swing * h * rng.standard_normal((19, h.size))
        err = swing * h * rng.standard_normal(h.size) if follows else 0.5 * h * rng.standard_normal(h.size)
        res.measured["roll_rad"] = err
        return res, devs

    for follows, weight in ((False, 0.0), (True, 1.0)):
        reps = [replay(61 + k, follows) for k in range(3)]
        disc = learn([r for r, _ in reps], ["a", "b", "c"])
        s = calibrate(disc, [(r, {"roll_rad": d}) for r, d in reps]).signals["roll_rad"]
        assert s.parameter_weight == weight, follows
        forced = calibrate(disc, [(r, {"roll_rad": d}) for r, d in reps], weights=(1.0,)).signals["roll_rad"]
        assert forced.parameter_weight == 1.0  # the study switch: the draws always in


def test_learning_with_parameter_draws_stores_a_factor_that_validate_applies(
    fixed_wing_fmu: Path, wing: dict[str, Path], tmp_path: Path, cluster: Any  # noqa: F811 - the fixtures
) -> None:
    """The discrepancy learned with the parameter draws of the learning flight stores one band factor per signal;
    validate --mc applies it (the metrics name it) and the held-out flight's bands stay near their level."""
    from identification.flights import synthetic
    from identification.validation.workflow import learn_discrepancy, validate_mc

    wrong = identified(scale=1.3)
    t, sig = synthetic.fixed_wing_flight(seconds=40.0, rate_hz=50.0, noise=True, seed=7)
    other = synthetic.write_csv_log(tmp_path / "other.csv", t, sig)
    job = _job(fixed_wing_fmu, wing, None)
    learn_job = job.__class__(fixed_wing_fmu, other, job.options, mapping=job.mapping)
    learned = learn_discrepancy(learn_job, [other], uncertainty=wrong, draws=19, executor=cluster)
    factors = {k: s.band_factor for k, s in learned.discrepancy.signals.items()}
    assert all(f is not None and 0.05 <= f <= 20.0 for f in factors.values()), factors
    assert any("band factor" in line for line in learned.lines())
    out = validate_mc(job, wrong, 19, seed=3, executor=cluster, discrepancy=learned.discrepancy)
    assert out.replay.bands.info["discrepancy"]["band_factor"] == factors
    # one learning flight: nothing to leave out, so the parameter draws stay in every band (weight 1)
    assert out.replay.bands.info["discrepancy"]["parameter_weight"] == dict.fromkeys(factors, 1.0)
    cov = {s: v["band_coverage"] for s, v in out.signals.items()}
    assert all(0.8 <= cov[s] <= 0.98 for s in IDENTIFIED), cov
    from identification.validation.report import validation_page

    page = validation_page(out.replay)  # the report: the band, its nominal level, its calibration, the coverage
    assert "Nominal level 90 %" in page and "5-95 % band coverage" in page
    assert f"roll_rad {factors['roll_rad']:.3g}" in page
    # weight 0 on roll: its band is the discrepancy alone (stretched), which the console, metrics and report name
    roll = learned.discrepancy.signals["roll_rad"]
    alone = learned.discrepancy.model_copy(update={"signals": {
        **learned.discrepancy.signals, "roll_rad": roll.model_copy(update={"parameter_weight": 0.0})}})
    out0 = validate_mc(job, wrong, 19, seed=3, executor=cluster, discrepancy=alone)
    assert out0.replay.bands.info["discrepancy"]["parameter_weight"]["roll_rad"] == 0.0
    assert any("the discrepancy alone on roll_rad" in line for line in out0.lines())
    assert "on roll_rad the discrepancy alone" in validation_page(out0.replay)
    b0, b1 = out0.replay.bands, out.replay.bands
    assert not np.allclose(b0.hi["roll_rad"] - b0.lo["roll_rad"], b1.hi["roll_rad"] - b1.lo["roll_rad"])
    np.testing.assert_array_equal(b0.hi["pitch_rad"], b1.hi["pitch_rad"])  # the other signals as they were
    # a table centred on a restart offset: the band moves by it (times the table's scale) and every output names it
    moved = roll.model_copy(update={"offset": 0.01, "quantiles": [[q + 0.01 for q in row] for row in roll.quantiles]})
    shifted = learned.discrepancy.model_copy(update={"signals": {**learned.discrepancy.signals, "roll_rad": moved}})
    out2 = validate_mc(job, wrong, 19, seed=3, executor=cluster, discrepancy=shifted)
    b2, scale = out2.replay.bands, scale_of(out.replay, "roll_rad", roll)
    ok = np.isfinite(b1.hi["roll_rad"])
    np.testing.assert_allclose((b2.hi["roll_rad"] - b1.hi["roll_rad"])[ok], (0.01 * scale)[ok], atol=1e-9)
    np.testing.assert_allclose((b2.lo["roll_rad"] - b1.lo["roll_rad"])[ok], (0.01 * scale)[ok], atol=1e-9)
    named = "roll_rad (+0.01 rad)" if roll.scale_floor is None else "roll_rad (+0.01 x ("
    assert any("band centred off the FMU on " + named in line for line in out2.lines()), out2.lines()
    assert "centred off the FMU on " + named in validation_page(out2.replay)
    assert not any("centred off the FMU" in line for line in out.lines())


def test_the_sign_is_kept_only_where_it_carries_from_one_learning_replay_to_another() -> None:
    """Two learning replays drifting the same way: the band keeps the sign (narrower, still covering the other);
    drifting opposite ways: the band is symmetric; one replay: symmetric (nothing shows the sign carries)."""
    def drifting(seed: int, sign: float) -> SimpleNamespace:
        res, _ = _replay(seed, n_windows=100)
        res.measured["roll_rad"] = sign * np.abs(res.measured["roll_rad"])
        return res

    same = learn([drifting(51, 1.0), drifting(52, 1.0)], ["a", "b"]).signals["roll_rad"]
    assert not same.symmetric and all(row[LEVELS.index(0.05)] >= -1e-3 for row in same.quantiles)
    opposite = learn([drifting(53, 1.0), drifting(54, -1.0)], ["a", "b"]).signals["roll_rad"]
    assert opposite.symmetric
    assert learn([drifting(55, 1.0)], ["a"]).signals["roll_rad"].symmetric


def test_a_bias_seen_at_the_restart_centres_the_band_where_it_carries_from_replay_to_replay() -> None:
    """A sensor bias (logged - FMU already 0.5 at the restart, where the dynamics have not yet erred) in both
    learning replays, whose drifts go opposite ways (so no signed band carries): the band is centred on the bias,
    symmetric about it, as wide as it would be without the bias, and covers a third replay at its level; biases of
    opposite signs, or a single replay: centred on the FMU."""
    def biased(seed: int, bias: float, drift: float, n_windows: int = 100) -> SimpleNamespace:
        res, _ = _replay(seed, sigma_per_s=0.5, n_windows=n_windows)
        res.measured["roll_rad"] = drift * np.abs(res.measured["roll_rad"]) + bias
        return res

    disc = learn([biased(61, 0.5, 1.0), biased(62, 0.5, -1.0)], ["a", "b"])
    s = disc.signals["roll_rad"]
    assert s.symmetric and s.offset == pytest.approx(0.5, abs=0.02)
    i5, i50, i95 = LEVELS.index(0.05), LEVELS.index(0.5), LEVELS.index(0.95)
    for row in s.quantiles:
        assert row[i50] == pytest.approx(s.offset) and row[i95] - s.offset == pytest.approx(s.offset - row[i5])
    unbiased = learn([biased(61, 0.0, 1.0), biased(62, 0.0, -1.0)], ["a", "b"]).signals["roll_rad"]
    assert unbiased.symmetric and unbiased.offset is None
    assert s.quantiles[-1][i95] - s.quantiles[-1][i5] == pytest.approx(
        unbiased.quantiles[-1][i95] - unbiased.quantiles[-1][i5], rel=0.1)  # the bias no longer widens it
    third = biased(63, 0.5, 1.0, n_windows=200)
    third.measured["roll_rad"] = 0.5 + (third.measured["roll_rad"] - 0.5) * np.sign(np.sin(np.arange(
        third.t_s.size)))  # drift of either sign
    lo, hi = _band(disc, third)
    r = third.measured["roll_rad"]
    assert 0.87 <= float(np.mean((r >= lo) & (r <= hi))) <= 0.93
    assert learn([biased(64, 0.5, 1.0), biased(65, -0.5, -1.0)], ["a", "b"]).signals["roll_rad"].offset is None
    assert learn([biased(66, 0.5, 1.0)], ["a"]).signals["roll_rad"].offset is None
