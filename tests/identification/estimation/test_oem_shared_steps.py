"""The output-error estimator's steps kept per problem and process: what its estimators share, what keys them,
and that sharing changes no number."""

from __future__ import annotations

import numpy as np

from fmu_models.common.simulate import Simulator
from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.trim import trim
from identification.estimation import oem
from identification.estimation.oem import Manoeuvre, OutputErrorEstimator


def test_estimators_of_one_problem_share_their_steps_and_record_maps_and_simulate_alike(monkeypatch) -> None:
    """Two output-error estimators of one problem (model structure, free set, estimated states, outputs) share
    their steps and the maps over each record length, and simulate bit for bit as an estimator with maps of its
    own; another free set, or another compiler (``$CC``, part of what the compiled library is), gets its own. A
    compiler that cannot run leaves the virtual machine, with the same values. The maps are bounded."""
    sim = Simulator(FixedWingModel())
    p = sim.params()
    free, outputs = ["C_ell_p", "C_n_r"], ["roll_rad", "rate_body_x_rad_s"]
    a = OutputErrorEstimator(sim.model, p, free, outputs, compile=False)
    b = OutputErrorEstimator(sim.model, p, list(free), list(outputs), compile=False)
    assert a._steps is b._steps
    assert OutputErrorEstimator(sim.model, p, ["C_ell_p"], outputs, compile=False)._steps is not a._steps
    tr = trim(sim.model, p, 25.0)
    n = 40
    u = np.tile(np.asarray(tr.u, float), (n, 1))
    u[10:20, 0] += 0.05
    m = Manoeuvre(np.asarray(tr.x, float), u, np.zeros((n, len(outputs))), 0.02)
    ya, Ja = a.simulate(p[a.i_free], m)[:2]
    assert a._steps.over_record("sensitivity", n) is b._steps.over_record("sensitivity", n)
    own = OutputErrorEstimator(sim.model, p, free, outputs, compile=False)
    own._steps = oem._Steps(own._steps.plain, own._steps.sens)  # the same steps, maps of its own
    yo, Jo = own.simulate(p[own.i_free], m)[:2]
    np.testing.assert_array_equal(ya, yo)
    np.testing.assert_array_equal(Ja, Jo)
    monkeypatch.setenv("CC", "/nonexistent/cc-one")
    c1 = OutputErrorEstimator(sim.model, p, free, outputs, compile=True)
    monkeypatch.setenv("CC", "/nonexistent/cc-two")
    c2 = OutputErrorEstimator(sim.model, p, free, outputs, compile=True)
    assert c1._steps is not c2._steps and c1._steps is not a._steps
    y1, J1 = c1.simulate(p[c1.i_free], m)[:2]  # no compiler ran: the virtual machine on the same equations
    np.testing.assert_allclose(y1, ya, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(J1, Ja, rtol=1e-9, atol=1e-12)
    steps = oem._Steps(a._steps.plain, a._steps.sens)
    for k in range(steps.MAPS_MAX + 5):
        steps.over_record("plain", k + 1)
    assert len(steps._maps) == steps.MAPS_MAX
    assert ("plain", 1) not in steps._maps and ("plain", steps.MAPS_MAX + 5) in steps._maps


def test_a_compiler_that_cannot_run_is_a_compile_error_naming_it(tmp_path) -> None:
    """``compile_library`` with a compiler path that does not exist raises ``CompileError`` naming it (the
    estimator then falls back to the virtual machine, the FMU build reports it), not an OSError from the
    process launch."""
    import pytest

    from fmu_models.fmi.codegen import CompileError, compile_library

    src = tmp_path / "x.c"
    src.write_text("int f(void) { return 0; }\n")
    with pytest.raises(CompileError, match="/nonexistent/cc"):
        compile_library(src, tmp_path / "x.so", "/nonexistent/cc")
