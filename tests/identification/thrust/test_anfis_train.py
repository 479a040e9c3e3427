"""ANFIS hybrid training: forward pass equals AnfisMap.evaluate, gradients, recovery of known maps."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fmu_models.quadrotor.anfis import (
    PUBLISHED_FZ_N,
    PUBLISHED_MEAN_US,
    PUBLISHED_SIGMA_US,
    AnfisMap,
    published_map,
)
from identification.thrust import anfis_train as at
from identification.thrust.anfis_train import (
    AnfisTrainConfig,
    AnfisTrainingError,
    polynomial_baselines,
    predict,
    r_squared,
    rmse,
    train_anfis,
    training_forward,
)

NOISE_N = 0.2  #: noise of the benchmark problem [N]


def quadratic_thrust(x_us: np.ndarray) -> np.ndarray:
    """The benchmark's known map: 11.18 N at 6000 us summed, growing with PWM squared."""
    return 11.18 * (x_us / 6000.0) ** 2


def quadratic_data(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = rng.uniform(4800.0, 7200.0, n)
    return x, quadratic_thrust(x) + NOISE_N * rng.standard_normal(n)


@pytest.mark.parametrize("mf_type", ["gaussian", "gbell"])
@pytest.mark.parametrize("order", [0, 1])
@pytest.mark.parametrize("n_inputs", [1, 2])
def test_training_forward_equals_anfismap_evaluate(mf_type: str, order: int, n_inputs: int) -> None:
    rng = np.random.default_rng(1)
    x = np.column_stack([rng.uniform(5000.0, 7000.0, 400), rng.uniform(-3.0, 3.0, 400)])[:, :n_inputs]
    y = np.sin(x[:, 0] / 400.0) + (x[:, -1] ** 2 if n_inputs == 2 else 0.0)
    res = train_anfis(
        x,
        y,
        AnfisTrainConfig(n_mfs=3, mf_type=mf_type, order=order, epochs=15),
        input_names=tuple(f"u{i}" for i in range(n_inputs)),
    )
    xs = np.column_stack([rng.uniform(5000.0, 7000.0, 200), rng.uniform(-3.0, 3.0, 200)])[:, :n_inputs]
    ref = np.asarray(res.amap.evaluate([xs[:, i] for i in range(n_inputs)]))
    np.testing.assert_allclose(training_forward(res.amap, xs), ref, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(predict(res.amap, xs), ref, rtol=0, atol=0)


def test_published_tables_reproduce_the_map_exactly() -> None:
    """Tables 2-3 through the JSON schema give back the same numbers and eq. 2/4 outputs."""
    pm = published_map()
    loaded = AnfisMap.from_dict(json.loads(json.dumps(pm.to_dict())))
    assert loaded == pm
    assert loaded.mf_mean == (PUBLISHED_MEAN_US,) and loaded.mf_sigma == (PUBLISHED_SIGMA_US,)
    assert tuple(c[0] for c in loaded.consequents) == PUBLISHED_FZ_N
    x = np.linspace(5800.0, 6217.3, 50)
    mu = np.exp(-(((x[:, None] - np.array(PUBLISHED_MEAN_US)) / np.array(PUBLISHED_SIGMA_US)) ** 2))
    by_hand = mu @ np.array(PUBLISHED_FZ_N) / mu.sum(axis=1)  # eq. 2 and eq. 4 written out
    np.testing.assert_allclose(predict(loaded, x), by_hand, rtol=1e-14)
    np.testing.assert_allclose(training_forward(loaded, x), by_hand, rtol=1e-12)


@pytest.mark.parametrize("order", [0, 1])
def test_recovers_known_map_within_noise(order: int) -> None:
    x, y = quadratic_data(5000, seed=0)
    xt, yt = quadratic_data(2000, seed=1)
    res = train_anfis(x, y, AnfisTrainConfig(n_mfs=6, order=order, epochs=60))
    pred = predict(res.amap, xt)
    # the fit error against the noise-free map is far below the noise; against noisy data it is the noise
    assert rmse(pred, quadratic_thrust(xt)) < 0.25 * NOISE_N
    assert 0.95 * NOISE_N < rmse(pred, yt) < 1.05 * NOISE_N
    assert res.amap.input_range == ((float(x.min()), float(x.max())),)


def test_recovers_two_input_first_order_surface() -> None:
    rng = np.random.default_rng(3)
    x = rng.uniform(-1.0, 1.0, (3000, 2)) * [400.0, 2.0] + [6000.0, 0.0]
    f = lambda a: np.sin((a[:, 0] - 6000.0) / 150.0) + 0.5 * a[:, 1] ** 2  # noqa: E731
    sigma = 0.05
    res = train_anfis(
        x,
        f(x) + sigma * rng.standard_normal(3000),
        AnfisTrainConfig(n_mfs=4, order=1, epochs=80),
        input_names=("pwm_sum_us", "v"),
    )
    xt = rng.uniform(-0.9, 0.9, (1000, 2)) * [400.0, 2.0] + [6000.0, 0.0]
    assert rmse(predict(res.amap, xt), f(xt)) < sigma


@pytest.mark.parametrize("mf_type", ["gaussian", "gbell"])
@pytest.mark.parametrize("order", [0, 1])
def test_premise_gradient_matches_finite_differences(mf_type: str, order: int) -> None:
    rng = np.random.default_rng(4)
    z = rng.uniform(-1.0, 1.0, (300, 2))
    y = np.cos(2 * z[:, 0]) * z[:, 1]
    cfg = AnfisTrainConfig(n_mfs=3, mf_type=mf_type, order=order)
    rules = at._rule_index(2, 3)
    prem = at._grid_init(2, cfg)
    prem.mean = prem.mean + 0.05 * rng.standard_normal(prem.mean.shape)  # break symmetries
    logmu, u = at._log_memberships(z, prem)
    cons = at._least_squares(at._normalised_firing(logmu, rules), z, y, order, len(rules))
    grads, _ = at._premise_gradient(
        z, y, prem, cons, order, at._onehots(rules, 3), u, at._normalised_firing(logmu, rules)
    )

    def sse(p: at._Premise) -> float:
        e = y - at._forward(z, p, cons, rules, order)
        return float(e @ e)

    names = ["mean", "sigma"] + (["slope"] if mf_type == "gbell" else [])
    h = 1e-6
    for g, name in zip(grads, names, strict=True):
        for idx in [(0, 0), (1, 2), (0, 1)]:
            plus, minus = prem.copy(), prem.copy()
            getattr(plus, name)[idx] += h
            getattr(minus, name)[idx] -= h
            numeric = (sse(plus) - sse(minus)) / (2 * h)
            assert g[idx] == pytest.approx(numeric, rel=1e-5, abs=1e-6)


def test_step_size_follows_jang_rules() -> None:
    cfg = AnfisTrainConfig(step_size=0.01)
    grow = at._StepSize(cfg)
    for e in (5.0, 4.0, 3.0, 2.0, 1.0):  # four consecutive reductions
        grow.update(e)
    assert grow.kappa == pytest.approx(0.011)
    shrink = at._StepSize(cfg)
    for e in (5.0, 4.0, 4.5, 4.2, 4.4):  # down, up, down, up: two up-down combinations
        shrink.update(e)
    assert shrink.kappa == pytest.approx(0.009)
    steady = at._StepSize(cfg)
    for e in (5.0, 4.0, 3.0, 3.5):
        steady.update(e)
    assert steady.kappa == 0.01


def test_hybrid_learning_lowers_training_error() -> None:
    x, y = quadratic_data(2000, seed=5)
    res = train_anfis(x, y, AnfisTrainConfig(n_mfs=4, mf_type="gbell", order=0, epochs=40))
    assert res.train_rmse[-1] < 0.9 * res.train_rmse[0]
    assert res.best_epoch == int(np.argmin(res.train_rmse))


def test_checking_data_selects_the_best_epoch() -> None:
    x, y = quadratic_data(300, seed=6)
    xc, yc = quadratic_data(300, seed=7)
    res = train_anfis(x, y, AnfisTrainConfig(n_mfs=8, order=1, epochs=60), xc, yc)
    assert res.check_rmse is not None and len(res.check_rmse) == res.epochs_run == 60
    assert res.best_epoch == int(np.argmin(res.check_rmse))
    assert rmse(predict(res.amap, xc), yc) == pytest.approx(min(res.check_rmse), rel=1e-9)
    stopped = train_anfis(x, y, AnfisTrainConfig(n_mfs=8, order=1, epochs=60, patience=3), xc, yc)
    assert stopped.epochs_run <= res.epochs_run
    assert stopped.epochs_run == stopped.best_epoch + 4 or stopped.epochs_run == 60


def test_deterministic_and_scale_invariant() -> None:
    x, y = quadratic_data(1000, seed=8)
    cfg = AnfisTrainConfig(n_mfs=5, order=1, epochs=30)
    a = train_anfis(x, y, cfg)
    b = train_anfis(x, y, cfg)
    assert a.amap.to_dict() == b.amap.to_dict()
    kilo = train_anfis(x / 1000.0, y, cfg)  # the same data in ms instead of us
    np.testing.assert_allclose(predict(kilo.amap, x / 1000.0), predict(a.amap, x), rtol=1e-8)


def test_json_round_trip_keeps_predictions(tmp_path) -> None:
    x, y = quadratic_data(800, seed=9)
    res = train_anfis(x, y, AnfisTrainConfig(n_mfs=4, mf_type="gbell", order=1, epochs=10))
    path = tmp_path / "map.json"
    res.amap.save(path)
    loaded = AnfisMap.load(path)
    np.testing.assert_array_equal(predict(loaded, x), predict(res.amap, x))


def test_polynomial_baseline_is_exact_on_polynomial_data() -> None:
    x = np.linspace(5000.0, 7000.0, 50)
    y = 1e-6 * (x - 6000.0) ** 2 + 2e-3 * x
    fits = polynomial_baselines(x, y, x, y)
    assert [f.degree for f in fits] == [1, 2, 3]
    assert fits[0].test_rmse > 1e-2 and fits[1].test_rmse < 1e-9 and fits[2].test_rmse < 1e-9
    assert r_squared(fits[1](x), y) == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"n_mfs": 0}, "n_mfs = 0"),
        ({"mf_type": "triangle"}, "mf_type = 'triangle'"),
        ({"order": 2}, "order = 2"),
        ({"step_size": -1.0}, "step_size = -1.0"),
        ({"patience": 0}, "patience = 0"),
    ],
)
def test_bad_config_is_named(kwargs: dict, needle: str) -> None:
    with pytest.raises(AnfisTrainingError, match=needle.replace("(", r"\(")):
        AnfisTrainConfig(**kwargs)


def test_bad_data_is_named() -> None:
    x, y = quadratic_data(100, seed=10)
    bad = x.copy()
    bad[3] = np.nan
    with pytest.raises(AnfisTrainingError, match="finite"):
        train_anfis(bad, y)
    with pytest.raises(AnfisTrainingError, match="'pwm_sum_us' is constant"):
        train_anfis(np.full(100, 6000.0), y)
    with pytest.raises(AnfisTrainingError, match="fewer than the 12 consequent parameters"):
        train_anfis(x[:5], y[:5], AnfisTrainConfig(n_mfs=6, order=1))


def test_per_motor_training_recovers_a_known_motor_curve() -> None:
    """Total thrust of four motors at different commands trains one per-motor map G with y = sum_i G(u_i)."""
    rng = np.random.default_rng(3)
    u = rng.uniform(0.2, 0.9, (3000, 4))

    def motor(x: np.ndarray) -> np.ndarray:
        return 8.0 * x**2 * (1.0 - 0.3 * x)  # N per motor, flattening at the top

    y = motor(u).sum(axis=1) + 0.05 * rng.standard_normal(3000)
    res = at.train_feature_anfis(u[:2400], None, y[:2400], ("x2", "x"), 2, epochs=40,
                                 check=(u[2400:], None, y[2400:]))
    grid = np.linspace(0.25, 0.85, 50)
    np.testing.assert_allclose(predict(res.amap, grid), motor(grid), atol=0.05)
    assert at.feature_map_monotone(res.amap) and res.amap.input_range[0] == pytest.approx((0.2, 0.9), abs=1e-3)
    assert res.check_rmse is not None and min(res.check_rmse) < 0.07


def test_single_rule_feature_anfis_is_the_least_squares_polynomial_to_1e_9() -> None:
    """One rule with first-order consequents over (u^2, u) per motor IS the least-squares
    polynomial a sum u^2 + b sum u; also through the FMU's thrust function and the workflow's baseline."""
    from fmu_models.quadrotor.params import QuadrotorParams
    from identification.thrust.model import FlightData, ModelSpec, baseline_predictions, fit, fmu_total_thrust

    rng = np.random.default_rng(3)
    n = 3000
    pwm = 1000.0 + 1000.0 * np.clip(0.6 + 0.1 * rng.standard_normal((n, 1)) + 0.03 * rng.standard_normal((n, 4)),
                                    0.3, 0.95)
    u = (pwm - 1000.0) / 1000.0
    y = (7.0 * u**2 + 2.5 * u + 0.4 * np.sin(7 * u)).sum(axis=1) + 0.3 * rng.standard_normal(n)
    res = at.train_feature_anfis(u, None, y, ("x2", "x"), 1)
    design = np.stack([(u**2).sum(axis=1), u.sum(axis=1)], axis=1)
    coef = np.linalg.lstsq(design, y, rcond=None)[0]
    np.testing.assert_allclose(res.amap.consequents[0], coef, rtol=0, atol=1e-9)
    flight = FlightData("f", pwm, None, np.ones(n, bool), np.arange(n) * 0.1, y, 12.0, 0.1)
    spec = ModelSpec(1000.0, 2000.0, 11.1, False)
    p = fit([flight], spec, 30, 5.0, "test").params
    assert isinstance(p, QuadrotorParams) and p.thrust_map.n_rules == 1
    fmu = fmu_total_thrust(p, pwm, np.full(n, 11.1))  # the FMU's function, band extension included
    poly = baseline_predictions([flight], flight, spec)["poly sum u^2, sum u"]
    np.testing.assert_allclose(fmu, poly, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fmu, design @ coef, rtol=0, atol=1e-9)


def test_more_feature_rules_fit_a_curved_motor_better_and_stay_zero_at_idle() -> None:
    rng = np.random.default_rng(4)
    u = np.clip(0.6 + 0.15 * rng.standard_normal((4000, 1)) + 0.03 * rng.standard_normal((4000, 4)), 0.3, 0.95)
    y = (10.0 * u**2 * (1.0 - 0.6 * (u - 0.6) ** 2) + 3.0 * np.tanh(8 * (u - 0.6)) + 3.0).sum(axis=1)
    one = at.train_feature_anfis(u, None, y, ("x2", "x"), 1)
    three = at.train_feature_anfis(u, None, y, ("x2", "x"), 3, epochs=60)
    assert min(three.train_rmse) < 0.7 * one.train_rmse[0]
    assert float(three.amap.evaluate([np.array([0.0])])[0]) == 0.0
