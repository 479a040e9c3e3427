"""Geometry priors (textbook numbers), user priors, the MAP term, the consider
covariance of parameters held fixed at a wrong value, and the auto-freeing rule."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from identification.aero.priors import PriorError, fixed_sd, geometry_priors, lift_slope, parse_priors
from identification.estimation.oem import OutputErrorEstimator, consider_covariance, fixed_worth_freeing
from identification.flights.synthetic import identification_manoeuvres

OUT = ["roll_rad", "rate_body_x_rad_s", "rate_body_z_rad_s", "accel_body_y_m_s2"]


def test_lift_slope_and_strip_theory_match_the_textbook_numbers() -> None:
    assert lift_slope(1e6) == pytest.approx(2 * math.pi, rel=1e-5)  # thin-airfoil limit
    assert lift_slope(6.0) == pytest.approx(2 * math.pi * 6 / (2 + math.sqrt(40.0)), rel=1e-12)  # 4.53 /rad
    g = geometry_priors({"b_m": 3.0, "S_wing_m2": 0.5, "c_m": 0.2})  # aspect ratio 18
    a_w = lift_slope(18.0)
    assert g["C_ell_p"].value == pytest.approx(-a_w / 6.0)  # rectangular wing, lambda = 1: -a/6
    assert g["C_m_q"].value < g["C_m_alpha"].value < 0 < g["C_n_beta"].value
    assert g["C_n_r"].value < 0 and g["C_Y_beta"].value < 0
    assert all(v.sd > 0 and v.source == "geometry" for v in g.values())
    # larger tail arm / chord ratio -> more pitch damping
    assert geometry_priors({"b_m": 3.0, "S_wing_m2": 0.5, "c_m": 0.1})["C_m_q"].value < g["C_m_q"].value


def test_user_priors_parse_and_bad_ones_are_named() -> None:
    known = set(FixedWingParams().to_dict())
    pri = parse_priors("C_ell_p=-0.5:0.1, C_n_r=-0.1:0.05", known)
    assert pri["C_ell_p"].value == -0.5 and pri["C_n_r"].sd == 0.05 and pri["C_ell_p"].source == "user"
    for bad, word in (("C_ell_p=-0.5", "name=value:sd"), ("C_ell_p=-0.5:0", "sd > 0"),
                      ("C_ell_pp=-0.5:0.1", "C_ell_pp"), ("C_ell_p=nan:0.1", "finite")):
        with pytest.raises(PriorError, match=word):
            parse_priors(bad, known)
    assert fixed_sd("C_n_p", 0.069) == pytest.approx(0.0345) and fixed_sd("C_ell_0", 0.0) == 0.005


@pytest.fixture(scope="module")
def lateral():  # type: ignore[no-untyped-def]
    sim = Simulator(FixedWingModel())
    p = sim.params(density_altitude_scaling=0.0)
    plant = OutputErrorEstimator(sim.model, p, ["C_ell_p"], OUT)
    rng = np.random.default_rng(3)
    data = identification_manoeuvres(plant, p, 6.0, 50.0, 4, rng, np.array([0.003, 0.005, 0.005, 0.05]))
    return sim, p, data


def test_a_tight_prior_pins_the_estimate_and_a_wide_one_leaves_it_to_the_data(lateral) -> None:  # type: ignore[no-untyped-def]
    sim, p, data = lateral
    free = ["C_ell_p", "C_ell_delta_a"]
    plain = OutputErrorEstimator(sim.model, p, free, OUT).estimate(data, max_iter=30)
    tight = OutputErrorEstimator(sim.model, p, free, OUT, prior={"C_ell_p": (-0.3, 1e-5)}).estimate(data, max_iter=30)
    wide = OutputErrorEstimator(sim.model, p, free, OUT, prior={"C_ell_p": (-0.3, 10.0)}).estimate(data, max_iter=30)
    assert tight.values[0] == pytest.approx(-0.3, abs=1e-4) and tight.dominance()[0] == "prior"
    assert "C_ell_p" in tight.prior_dominated() and tight.std[0] <= 1e-5 * 1.01
    assert abs(wide.values[0] - plain.values[0]) < 0.1 * plain.std[0] and wide.dominance()[0] == "data"
    assert plain.dominance()[0] == "data (no prior)"
    assert plain.values[0] == pytest.approx(-0.51, abs=4 * plain.std[0])


def test_consider_covariance_predicts_the_shift_from_a_wrong_fixed_value(lateral) -> None:  # type: ignore[no-untyped-def]
    """Fit with C_n_p and C_ell_r held 30 % off the plant's: the linearised influence predicts the shift of the
    free derivatives; the consider bound covers it, the data bound alone does not."""
    sim, p, data = lateral
    free = ["C_ell_p", "C_ell_delta_a", "C_n_r", "C_n_delta_r"]
    truth = OutputErrorEstimator(sim.model, p, free, OUT).estimate(data, max_iter=30)
    wrong = p.copy()
    for n in ("C_n_p", "C_ell_r"):
        wrong[sim.model.params.index[n]] *= 1.3
    oe = OutputErrorEstimator(sim.model, wrong, free, OUT)
    est = oe.estimate(data, max_iter=30)
    sd = {"C_n_p": fixed_sd("C_n_p", 0.069), "C_ell_r": fixed_sd("C_ell_r", 0.25)}
    con = consider_covariance(oe, est, data, sd)
    delta = np.array([wrong[sim.model.params.index[n]] - p[sim.model.params.index[n]] for n in con.names])
    predicted = -con.influence @ delta  # estimate at the wrong value minus estimate at the right one
    shift = est.values[:4] - truth.values[:4]
    assert np.allclose(shift, predicted, rtol=0.3, atol=0.2 * truth.std[:4].max()), (shift, predicted)
    est.consider_cov = con.cov
    assert np.any(np.abs(shift) > 1.96 * est.data_std)  # the data bound alone misses the mismatch
    assert np.all(np.abs(shift) <= 1.96 * est.std[:4])  # with the consider share it covers it
    assert "C_ell_r" in fixed_worth_freeing(est, con)  # matters and the roll data inform it


def test_a_horizon_step_that_diverges_says_how_far_it_fitted(lateral) -> None:  # type: ignore[no-untyped-def]
    """Continuation from an unstable roll start: the short spans simulate, a longer one diverges; the error
    names the last span that fitted (identify aero then cuts its segments to that length)."""
    from identification.estimation.oem import HorizonDivergedError

    sim, p, data = lateral
    oe = OutputErrorEstimator(sim.model, p, ["C_ell_p"], OUT)
    with pytest.raises(HorizonDivergedError) as err:
        oe.estimate(data, theta0=[0.1], max_iter=0, horizon_s=0.2)
    assert 0.2 <= err.value.last_ok_s < 6.0 and "diverges over" in str(err.value)


def test_two_logs_pool_into_one_estimate(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from fmu_models.signals.pwm_mapping import PwmMapping
    from identification.aero import model as aero
    from identification.aero.identify import AeroOptions, AeroSource, identify_aero
    from identification.flights import synthetic
    from identification.logs.readers import read_log

    mapping = PwmMapping.load(synthetic.write_mapping_toml(tmp_path / "m.toml"))
    sources = []
    for k in range(2):
        t, sig = synthetic.fixed_wing_flight(seconds=20.0, rate_hz=50.0, noise=True, seed=k)
        log = read_log(synthetic.write_csv_log(tmp_path / f"f{k}.csv", t, sig))
        sources.append(AeroSource(log, mapping, segments=[aero.Segment(0.0, 9.0)],
                                  validate_segments=[aero.Segment(10.0, 19.0)]))
    free = ["C_ell_p", "C_ell_delta_a", "C_n_r", "C_n_delta_r"]
    res = identify_aero(sources, None, FixedWingParams(), AeroOptions(
        free=free, outputs=("roll_rad", "rate_body_x_rad_s", "rate_body_z_rad_s"), max_delay_s=0.0,
        nuisance="none", equation_error=False, consider=False))
    assert len(res.fit.data) == 2 and len(res.validation_segments) == 2
    truth = FixedWingParams().to_dict()
    d = res.estimate.derivatives()
    for n in free:
        i = res.estimate.names.index(n)
        assert abs(d[n] - truth[n]) <= 4 * res.estimate.std[i] and res.estimate.std[i] < 0.1 * abs(truth[n]), n
