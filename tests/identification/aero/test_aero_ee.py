"""The equation-error estimate (trapezoidal increments, stepwise regression) on a noise-free
synthetic flight, and the stepwise regression on a linear problem with known terms."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.aero import model as aero
from identification.aero.equation_error import equation_error, stepwise
from identification.aero.identify import AeroSource
from identification.flights import synthetic
from identification.logs.readers import read_log


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory) -> tuple[AeroSource, FixedWingModel]:
    d: Path = tmp_path_factory.mktemp("ee")
    t, sig = synthetic.fixed_wing_flight(seconds=40.0, rate_hz=50.0)
    log = read_log(synthetic.write_csv_log(d / "flight.csv", t, sig))
    mapping = PwmMapping.load(synthetic.write_mapping_toml(d / "mapping.toml"))
    return AeroSource(log, mapping), FixedWingModel(FixedWingParams())


def test_equation_error_recovers_the_derivatives_of_a_noise_free_flight(flight) -> None:  # type: ignore[no-untyped-def]
    src, model = flight
    p = np.array(model.params.starts(), dtype=float)
    ee = equation_error(model, p, [src], [(0, aero.Segment(0.5, 39.0))], 50.0)
    truth = FixedWingParams().to_dict()
    tol = {"C_m_alpha": 0.02, "C_m_q": 0.02, "C_m_delta_e": 0.02, "C_n_beta": 0.04, "C_n_r": 0.04,
           "C_n_delta_r": 0.04, "C_ell_p": 0.12, "C_ell_delta_a": 0.12, "C_ell_beta": 0.12, "C_ell_r": 0.12,
           "C_Y_beta": 0.06}
    for name, rel in tol.items():
        assert ee.values[name] == pytest.approx(truth[name], rel=rel), (name, ee.values[name], truth[name])
    assert ee.r_squared["C_m"] > 0.9 and ee.r_squared["C_n"] > 0.99
    assert any("no wind" in n for n in ee.notes)


def test_stepwise_regression_keeps_the_terms_that_matter_and_drops_the_rest() -> None:
    rng = np.random.default_rng(1)
    n = 2000
    X = {k: rng.normal(size=n) for k in ("a", "b", "c", "d")}
    y = 1.5 + 2.0 * X["a"] - 0.7 * X["c"] + rng.normal(0.0, 0.1, n)
    terms, coef, std, r2 = stepwise(y, X)
    assert sorted(terms) == ["a", "c"]
    got = dict(zip(terms, coef, strict=True))
    assert got["a"] == pytest.approx(2.0, abs=4 * std[terms.index("a")])
    assert got["c"] == pytest.approx(-0.7, abs=4 * std[terms.index("c")])
    assert r2 > 0.99
