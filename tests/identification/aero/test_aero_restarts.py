"""``AeroOptions.restart_horizons_s``: each cold output-error fit is restarted with other continuation schedules
from the same start and the fit with the lowest criterion is kept. The law is checked on an estimator whose
minimum depends on the schedule (the estimator's own behaviour on long lateral records: a replica truth where
1 s spans end far above the truth's minimum and 2 s spans reach it, bench/aero_replica.py); the options are
bounded before any fit runs, and the CLI's ``--restarts`` reaches them."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from identification.aero import identify as ai
from identification.aero.identify import AeroInputError, AeroOptions
from identification.estimation.oem import Estimate, EstimationError, Manoeuvre

DATA = [Manoeuvre(np.zeros(3), np.zeros((100, 1)), np.zeros((100, 2)), 0.02, "m0")]


@dataclass
class Landscape:
    """An estimator whose fit ends where its continuation schedule leads: per first span [s] the residual std
    the fit reaches, whether it converges, or an error; ``prior`` is the prior term at every estimate."""

    ends: dict[float | None, float | str]
    converged: dict[float | None, bool] = field(default_factory=dict)
    prior: float = 0.0
    calls: list[float | None] = field(default_factory=list)

    def estimate(self, data, weight=None, max_iter=40, progress=False, horizon_s=None, theta0=None):  # type: ignore[no-untyped-def]
        self.calls.append(horizon_s)
        end = self.ends[horizon_s]
        if isinstance(end, str):
            raise EstimationError(end)
        return Estimate(names=["a"], values=np.array([end]), crb_std=np.ones(1), crb_std_white=np.ones(1),
                        correlation=np.eye(1), residual_cov=np.eye(2) * end**2,
                        converged=self.converged.get(horizon_s, True), n_global=1)

    def prior_cost(self, theta, data=None) -> float:  # type: ignore[no-untyped-def]
        return self.prior


def test_the_lowest_criterion_over_the_schedules_is_kept_and_every_schedule_named() -> None:
    oe = Landscape({1.0: 1.0, 0.5: 0.9, 2.0: 0.01})
    notes: list[str] = []
    fit = ai._cold_fit(oe, DATA, AeroOptions(), None, notes)  # type: ignore[arg-type]
    assert oe.calls == [1.0, 0.5, 2.0]
    assert fit.estimate.values[0] == 0.01
    n = 100  # the criterion is n ln det R: 2 outputs, variance 1 vs 1e-4 -> n * 2 ln 1e4 apart
    (note,) = [x for x in notes if "restarts" in x]
    assert f"1 s spans +{n * 2 * math.log(1e4):.0f}" in note and "2 s spans +0" in note
    assert "kept the 2 s spans" in note and "several minima" in note


def test_close_minima_are_not_called_several() -> None:
    notes: list[str] = []
    fit = ai._cold_fit(Landscape({1.0: 1.0, 0.5: 1.001, 2.0: 1.002}), DATA, AeroOptions(), None, notes)  # type: ignore[arg-type]
    assert fit.estimate.values[0] == 1.0
    assert "kept the 1 s spans" in notes[-1] and "several minima" not in notes[-1]


def test_a_restart_no_better_than_the_tie_keeps_the_first_schedules_fit() -> None:
    """A restart lower by less than RESTART_TIE reached the same minimum (or one no better): the first
    schedule's fit is kept, so the default's estimates stay as they were where the schedules agree."""
    n = 100
    just_below = math.exp(-(ai.RESTART_TIE - 0.5) / (2 * n) / 2)  # std factor: criterion lower by TIE - 0.5
    clearly_below = math.exp(-(ai.RESTART_TIE + 0.5) / (2 * n) / 2)
    notes: list[str] = []
    fit = ai._cold_fit(Landscape({1.0: 1.0, 0.5: just_below, 2.0: 1.0}), DATA, AeroOptions(), None, notes)  # type: ignore[arg-type]
    assert fit.estimate.values[0] == 1.0 and "kept the 1 s spans" in notes[-1]
    fit = ai._cold_fit(Landscape({1.0: 1.0, 0.5: clearly_below, 2.0: 1.0}), DATA, AeroOptions(), None, [])  # type: ignore[arg-type]
    assert fit.estimate.values[0] == clearly_below


def test_the_lowest_criterion_is_kept_whether_or_not_it_converged_and_the_note_says_which_did_not() -> None:
    """A lower criterion is a better point whether or not its fit stopped at max_iter (the warm refits go on from
    it); a converged fit in a higher minimum is not preferred."""
    oe, notes = Landscape({1.0: 1.0, 0.5: 0.1, 2.0: 0.5}, converged={0.5: False, 1.0: False}), []
    fit = ai._cold_fit(oe, DATA, AeroOptions(), None, notes)  # type: ignore[arg-type]
    assert fit.estimate.values[0] == 0.1
    assert "0.5 s spans +0 (not converged)" in notes[-1] and "1 s spans" in notes[-1]
    assert "2 s spans +" in notes[-1] and "2 s spans +0" not in notes[-1]
    assert notes[-1].count("(not converged)") == 2


def test_the_prior_term_enters_the_criterion() -> None:
    """Twice the prior term is added: a fit 1 % better in its residuals but far from its prior loses."""
    class Priced(Landscape):
        def prior_cost(self, theta, data=None) -> float:  # type: ignore[no-untyped-def]
            return 1e6 if theta[0] < 1.0 else 0.0

    fit = ai._cold_fit(Priced({1.0: 1.0, 0.5: 0.99, 2.0: 1.0}), DATA, AeroOptions(), None, [])  # type: ignore[arg-type]
    assert fit.estimate.values[0] == 1.0


def test_a_failed_restart_is_named_and_the_others_compared() -> None:
    notes: list[str] = []
    fit = ai._cold_fit(Landscape({1.0: 1.0, 0.5: "the model diverges", 2.0: 0.5}), DATA, AeroOptions(), None,  # type: ignore[arg-type]
                       notes)
    assert fit.estimate.values[0] == 0.5
    assert any("restart with 0.5 s continuation spans failed (the model diverges)" in x for x in notes)


def test_the_first_schedules_error_propagates() -> None:
    with pytest.raises(EstimationError, match="diverges"):
        ai._cold_fit(Landscape({1.0: "diverges", 0.5: 1.0, 2.0: 1.0}), DATA, AeroOptions(), None, [])  # type: ignore[arg-type]


def test_no_restarts_is_one_fit_without_a_note() -> None:
    oe, notes = Landscape({1.0: 1.0}), []
    ai._cold_fit(oe, DATA, AeroOptions(restart_horizons_s=()), None, notes)  # type: ignore[arg-type]
    assert oe.calls == [1.0] and notes == []


@pytest.mark.parametrize(("restarts", "needle"), [
    ((0.5, 1.5, 2.0, 3.0, 4.0), "at most 4 restarts"),
    ((0.01,), "restart horizon 0.01 s"),
    ((float("nan"),), "restart horizon nan s"),
    ((1e4,), "needs 0.05..600 s"),
])
def test_restarts_are_bounded_before_any_fit(restarts, needle) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(AeroInputError, match="restart") as err:
        ai._check_names(FixedWingModel(FixedWingParams()), AeroOptions(restart_horizons_s=restarts))
    assert needle in str(err.value)


@pytest.mark.parametrize("horizon", [0.0, -1.0, float("nan"), 1e4])
def test_the_first_horizon_is_bounded_as_the_restarts_are(horizon: float) -> None:
    with pytest.raises(AeroInputError, match=f"horizon {horizon!r} s"):
        ai._check_names(FixedWingModel(FixedWingParams()), AeroOptions(horizon_s=horizon))


def test_the_cli_passes_restarts_to_the_options() -> None:
    import argparse

    from uavfmu.commands import identify_aero as cmd

    parser = argparse.ArgumentParser()
    cmd.add_arguments(parser)

    def restarts(*extra: str) -> tuple[float, ...]:
        return tuple(cmd._options(parser.parse_args(["x.BIN", "--out", "x.json", *extra])).restart_horizons_s)

    assert restarts("--restarts", "0.25,3") == (0.25, 3.0)
    assert restarts("--restarts", "none") == ()
    assert restarts() == tuple(AeroOptions().restart_horizons_s)
    with pytest.raises(ValueError, match="--restarts"):
        restarts("--restarts", "a,b")
