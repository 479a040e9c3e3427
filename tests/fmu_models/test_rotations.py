"""The one rotation module: laws (orthonormal, inverse pairs, a known 90 deg yaw) and agreement of backends."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fmu_models.common import rigid_body
from fmu_models.common.mathns import CA, NP, PY
from fmu_models.common.rotations import (
    euler_to_dcm_rows,
    euler_to_quat,
    quat_to_dcm_rows,
    quat_to_euler,
    transpose_apply,
)

angles = st.tuples(st.floats(-3.1, 3.1), st.floats(-1.5, 1.5), st.floats(-3.1, 3.1))


@settings(max_examples=200, deadline=None, derandomize=True)
@given(angles)
def test_quaternion_and_euler_give_the_same_orthonormal_matrix(rpy: tuple[float, float, float]) -> None:
    q = euler_to_quat(*rpy, PY)
    assert math.isclose(sum(c * c for c in q), 1.0, rel_tol=1e-12)
    rq = np.array(quat_to_dcm_rows(*q))
    re = np.array(euler_to_dcm_rows(*rpy, PY))
    np.testing.assert_allclose(rq, re, atol=1e-12)
    np.testing.assert_allclose(rq @ rq.T, np.eye(3), atol=1e-12)
    assert math.isclose(np.linalg.det(rq), 1.0, rel_tol=1e-12)
    back = quat_to_euler(*q, PY)
    np.testing.assert_allclose(back, rpy, atol=1e-9)
    v = (0.3, -1.2, 2.5)
    np.testing.assert_allclose(transpose_apply(tuple(map(tuple, rq)), v), rq.T @ np.array(v), atol=1e-12)


def test_yaw_90_deg_turns_body_x_to_east() -> None:
    r = np.array(quat_to_dcm_rows(*euler_to_quat(0.0, 0.0, math.pi / 2, PY)))
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    # pitch up 90 deg: body x points up (NED -z)
    r = np.array(euler_to_dcm_rows(0.0, math.pi / 2, 0.0, PY))
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [0.0, 0.0, -1.0], atol=1e-15)


def test_numpy_casadi_and_float_backends_agree() -> None:
    rng = np.random.default_rng(3)
    rpy = rng.uniform([-3, -1.5, -3], [3, 1.5, 3], size=(50, 3))
    q_np = euler_to_quat(rpy[:, 0], rpy[:, 1], rpy[:, 2], NP)
    e_np = np.array(quat_to_euler(*q_np, NP))
    for i in (0, 17, 49):
        q_py = euler_to_quat(*rpy[i], PY)
        np.testing.assert_allclose([c[i] for c in q_np], q_py, atol=1e-14)
        q_ca = np.array(rigid_body.quat_from_euler(*rpy[i])).ravel()
        np.testing.assert_allclose(q_ca, q_py, atol=1e-14)
        np.testing.assert_allclose(np.array(rigid_body.quat_to_dcm(ca.DM(q_py))),
                                   np.array(quat_to_dcm_rows(*q_py)), atol=1e-14)
        np.testing.assert_allclose(np.array(rigid_body.euler_from_quat(ca.DM(q_py))).ravel(), e_np[:, i],
                                   atol=1e-12)
    np.testing.assert_allclose(e_np.T, rpy, atol=1e-9)
    assert CA.name == "casadi"
