"""``AeroOptions.initial_sd``: a segment's logged start as a measurement of an estimated initial state. The
options are checked before anything runs, the estimator gets the std of the states it estimates, and the CLI's
``--initial-sd`` reaches the options."""

from __future__ import annotations

import numpy as np
import pytest

from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from identification.aero import identify as ai
from identification.aero.identify import AeroInputError, AeroOptions

VEL = "vel_body_y_m_s"
RATES = ai.AUTO_STATES


@pytest.mark.parametrize(("opt", "needle"), [
    (AeroOptions(initial_sd={VEL: 0.05}), f"initial-state std {VEL}=0.05"),  # auto estimates the rates only
    (AeroOptions(nuisance="none", initial_sd={RATES[0]: 0.01}), "nuisance 'none'"),
    (AeroOptions(nuisance="given", estimate_initial=(VEL,), initial_sd={VEL: 0.0}), "finite std > 0"),
    (AeroOptions(nuisance="given", estimate_initial=(VEL,), initial_sd={VEL: float("inf")}), "finite std > 0"),
])
def test_a_std_for_a_state_not_estimated_or_not_positive_is_refused(opt, needle) -> None:
    with pytest.raises(AeroInputError, match="initial-state std") as err:
        ai._check_names(FixedWingModel(FixedWingParams()), opt)
    assert needle in str(err.value)


def test_the_estimator_gets_the_std_of_the_states_it_estimates() -> None:
    model = FixedWingModel(FixedWingParams())
    p = np.array(model.params.starts(), dtype=float)
    opt = AeroOptions(initial_sd={RATES[0]: 0.01})
    ai._check_names(model, opt)
    rich = ai._estimator(model, p, list(ai.PRIMARY), opt, RATES, ())
    plain = ai._estimator(model, p, list(ai.PRIMARY), opt, (), ())  # auto's fit without nuisance parameters
    assert rich.initial_sd == {RATES[0]: 0.01} and plain.initial_sd == {}
    np.testing.assert_allclose(rich.prior_information(len(ai.PRIMARY) + 2 * 3)[len(ai.PRIMARY):],
                               [1e4, 0.0, 0.0] * 2)


def test_the_cli_option_reaches_the_options() -> None:
    import argparse

    from uavfmu.commands import identify_aero as cmd

    parser = argparse.ArgumentParser()
    cmd.add_arguments(parser)
    args = parser.parse_args(["x.BIN", "--out", "x.json", "--estimate-initial", VEL, "--initial-sd", f"{VEL}=0.07"])
    assert cmd._options(args).initial_sd == {VEL: 0.07}
    with pytest.raises(ValueError, match="--initial-sd"):
        cmd._options(parser.parse_args(["x.BIN", "--out", "x.json", "--initial-sd", f"{VEL}=fast"]))


def test_the_given_set_names_each_prior() -> None:
    opt = AeroOptions(nuisance="given", estimate_initial=(RATES[0], VEL), biases=("accel_body_y_m_s2",),
                      initial_sd={VEL: 0.07})
    assert ai._given_text(opt) == (f"given: per-segment initial {RATES[0]}, {VEL} (logged start +- 0.07); "
                                   "biases of accel_body_y_m_s2")
