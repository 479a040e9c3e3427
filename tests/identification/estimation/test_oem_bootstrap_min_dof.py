"""The segment bootstrap enters a printed bound only with enough degrees of freedom (Estimate.bootstrap_min_dof)."""

from __future__ import annotations

import numpy as np
import pytest

from identification.estimation.oem import BOUND_METHODS, Estimate, student_factor


def _estimate(min_dof: float) -> Estimate:
    n = 3
    return Estimate(names=["a", "b", "c"], values=np.ones(n), crb_std=np.array([1.0, 1.0, 1.0]),
                    crb_std_white=np.full(n, 0.5), correlation=np.eye(n), residual_cov=np.eye(1), n_global=n,
                    bootstrap_std=np.array([3.0, 3.0, 0.5]), bound_method=BOUND_METHODS[1],
                    bootstrap_dof=np.array([2.0, 12.0, 30.0]), n_segments=20, bootstrap_min_dof=min_dof)


def test_default_keeps_the_bootstrap_in_every_bound():
    est = _estimate(0.0)
    want = np.maximum(1.0, np.array([3.0, 3.0, 0.5]) * student_factor(np.array([2.0, 12.0, 30.0])))
    assert est.std == pytest.approx(want)
    assert est.bootstrap_in_bound().all()


def test_a_bootstrap_with_too_few_degrees_of_freedom_is_left_out():
    est = _estimate(10.0)
    assert list(est.bootstrap_in_bound()) == [False, True, True]
    # a: 2 degrees of freedom, the coloured Cramer-Rao bound alone; b: the wider bootstrap with Student's factor;
    # c: the bootstrap enters but is narrower than the Cramer-Rao bound
    assert est.std == pytest.approx([1.0, 3.0 * student_factor(12.0), 1.0])
    # the printed covariance follows the printed bound
    assert np.sqrt(np.diag(est.covariance_printed())) == pytest.approx(est.std)
    params = est.as_dict()["parameters"]
    assert [params[n]["bootstrap_in_bound"] for n in "abc"] == [False, True, True]
