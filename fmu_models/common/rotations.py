"""Rotations written once for every scalar type: floats, numpy arrays of samples, CasADi expressions.

Frames: NED world, FRD body; ``q = [w, x, y, z]`` (scalar first) rotates body vectors into NED; Euler
angles are 3-2-1 (yaw, pitch, roll; paper 001 eq. 5). The matrix functions only multiply and add, so they
take any scalar type; the angle functions take a math namespace ``xp`` (``fmu_models.common.mathns``: ``PY``
for floats, ``NP`` for numpy arrays, ``CA`` for CasADi). ``rigid_body`` builds its CasADi matrices from
these, ``identification`` and ``hil_adapter`` call them with floats or arrays.
"""

from __future__ import annotations

from typing import Any

Rows = tuple[tuple[Any, Any, Any], tuple[Any, Any, Any], tuple[Any, Any, Any]]


def quat_to_dcm_rows(w: Any, x: Any, y: Any, z: Any) -> Rows:
    """Rows of ``R_b2n`` (body -> NED) of the unit quaternion ``[w, x, y, z]``."""
    return (
        (w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z),
    )


def euler_to_dcm_rows(roll_rad: Any, pitch_rad: Any, yaw_rad: Any, xp: Any) -> Rows:
    """Rows of ``R_b2n`` (body -> NED) of 3-2-1 Euler angles [rad]."""
    cr, sr = xp.cos(roll_rad), xp.sin(roll_rad)
    cp, sp = xp.cos(pitch_rad), xp.sin(pitch_rad)
    cy, sy = xp.cos(yaw_rad), xp.sin(yaw_rad)
    return (
        (cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy),
        (cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy),
        (-sp, sr * cp, cr * cp),
    )


def quat_to_euler(w: Any, x: Any, y: Any, z: Any, xp: Any) -> tuple[Any, Any, Any]:
    """Roll, pitch, yaw [rad] (3-2-1; paper 001 eq. 5) of ``[w, x, y, z]``; the homogeneous form, so a
    quaternion slightly off unit norm still gives the right roll and yaw."""
    roll = xp.atan2(2 * (w * x + y * z), w * w + z * z - x * x - y * y)
    pitch = xp.asin(xp.fmin(xp.fmax(2 * (w * y - x * z), -1.0), 1.0))
    yaw = xp.atan2(2 * (w * z + x * y), w * w + x * x - y * y - z * z)
    return roll, pitch, yaw


def euler_to_quat(roll_rad: Any, pitch_rad: Any, yaw_rad: Any, xp: Any) -> tuple[Any, Any, Any, Any]:
    """Unit quaternion ``[w, x, y, z]`` of 3-2-1 Euler angles [rad]."""
    cr, sr = xp.cos(roll_rad / 2), xp.sin(roll_rad / 2)
    cp, sp = xp.cos(pitch_rad / 2), xp.sin(pitch_rad / 2)
    cy, sy = xp.cos(yaw_rad / 2), xp.sin(yaw_rad / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def transpose_apply(rows: Rows, v: Any) -> tuple[Any, Any, Any]:
    """``Rᵀ v`` (e.g. NED -> body with ``R_b2n``) without building a matrix object."""
    return (
        rows[0][0] * v[0] + rows[1][0] * v[1] + rows[2][0] * v[2],
        rows[0][1] * v[0] + rows[1][1] * v[1] + rows[2][1] * v[2],
        rows[0][2] * v[0] + rows[1][2] * v[1] + rows[2][2] * v[2],
    )
