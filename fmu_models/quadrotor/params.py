"""Quadrotor parameters: DJI F450 of paper 000 Table 1, literature values where the paper has none."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from fmu_models.common.errors import ParameterError, ProblemList
from fmu_models.common.params import file_keys, param, read_json, validate_params, vehicle_table
from fmu_models.quadrotor.anfis import AnfisMap, published_map
from fmu_models.quadrotor.constants import MASS_KG, N_MOTORS, PWM_FULL_US, PWM_IDLE_US
from fmu_models.quadrotor.thrust import FEATURE_INPUTS

FRAMES = ("x", "+")
#: keys of a parameter file beside the scalar parameters: (type, default) checked by the schema
FILE_EXTRAS = {"frame": (Literal["x", "+"], "x"), "thrust_map": (dict[str, Any] | None, None),
               "k_thrust_source": (str, "")}


#: parameters renamed since 0.1.0 (inertia named as the fixed wing's and the Aerosonde set's: Jx, Jy, Jz)
RENAMED = {f"J{a}{a}_kg_m2": f"renamed J{a}_kg_m2 (the same value); rename the key" for a in "xyz"}


@dataclass(frozen=True)
class QuadrotorParams:
    """Physical parameters of a quadrotor (SI units).

    Mass, inertia and arm length: paper 000 Table 1 (DJI F450). Paper 000 gives no numbers for k, b,
    J_m or the drag; the defaults are those of the F450-sized quadrotor in T. Luukkonen, "Modelling and
    control of quadcopter", Aalto University, 2011, Table 1 (k = 2.980e-6 N s^2, b = 1.140e-7 N m s^2,
    I_M = 3.357e-5 kg m^2, A_x = A_y = A_z = 0.25 kg/s).
    """

    mass_kg: float = param(MASS_KG, "kg", 0.05, 50.0, "vehicle mass (paper 000 Table 1)")
    Jx_kg_m2: float = param(0.007, "kg.m2", 1e-5, 10.0, "inertia about body x (paper 000 Table 1)")
    Jy_kg_m2: float = param(0.007, "kg.m2", 1e-5, 10.0, "inertia about body y (paper 000 Table 1)")
    Jz_kg_m2: float = param(0.013, "kg.m2", 1e-5, 10.0, "inertia about body z (paper 000 Table 1)")
    arm_length_m: float = param(0.220, "m", 0.02, 5.0, "arm length l, CG to motor (paper 000 Table 1)")
    k_thrust_N_s2: float = param(2.980e-6, "N.s2", 1e-9, 1e-2, "thrust constant k, T_i = k Omega_i^2 (eq. 6)")
    b_drag_N_m_s2: float = param(1.140e-7, "N.m.s2", 0.0, 1e-3, "fan torque constant b (eq. 10)")
    J_rotor_kg_m2: float = param(3.357e-5, "kg.m2", 0.0, 1e-2, "rotor moment of inertia J_m (eq. 9)")
    kd_x_N_s_m: float = param(0.25, "N.s/m", 0.0, 100.0, "linear drag along body x (eq. 7)")
    kd_y_N_s_m: float = param(0.25, "N.s/m", 0.0, 100.0, "linear drag along body y (eq. 7)")
    kd_z_N_s_m: float = param(0.25, "N.s/m", 0.0, 100.0, "linear drag along body z (eq. 7)")
    tau_motor_s: float = param(0.0, "s", 0.0, 2.0, "first-order motor thrust time constant (0: none)")
    pwm_idle_us: float = param(PWM_IDLE_US, "us", 800.0, 1500.0, "per-motor PWM at and below which thrust is 0")
    pwm_full_us: float = param(PWM_FULL_US, "us", 1000.0, 2500.0, "per-motor PWM of full command u = 1 (feature maps)")
    battery_nominal_V: float = param(
        11.1, "V", 1.0, 100.0, "battery voltage the thrust map refers to (start of the voltage input)"
    )
    thrust_voltage_exponent: float = param(
        1.0, "1", 0.0, 3.0,
        "(V / battery_nominal_V)^this scales the thrust (feature maps) or the command above idle (summed maps)"
    )
    thrust_scale: float = param(1.0, "1", 0.2, 5.0, "per-flight thrust calibration factor (1: none)")
    ground_mu: float = param(0.5, "1", 0.0, 2.0, "friction coefficient of the landing gear")
    step_internal_s: float = param(0.001, "s", 1e-5, 0.05, "largest internal RK4 step")
    frame: str = "x"
    thrust_map: AnfisMap = field(default_factory=published_map)

    @property
    def n_motors(self) -> int:
        return N_MOTORS

    @classmethod
    def from_dict(cls, values: dict[str, Any], source: str = "quadrotor parameters") -> QuadrotorParams:
        """Defaults overridden by ``values``; every problem in ``values`` is reported at once."""
        scalars = validate_params(cls, values, source, extra=FILE_EXTRAS, retired=RENAMED)
        scalars.pop("k_thrust_source", None)
        frame = scalars.pop("frame", "x")
        probs = ProblemList(source)
        thrust_map = published_map()
        if scalars.pop("thrust_map", None) is not None:
            try:
                thrust_map = AnfisMap.from_dict(values["thrust_map"], source=f"{source}: thrust_map")
            except ParameterError as err:
                probs.items.extend(f"thrust_map: {p}" for p in err.problems)
        _check_map(probs, thrust_map, scalars.get("pwm_idle_us", PWM_IDLE_US), scalars.get("pwm_full_us", PWM_FULL_US))
        _check_motor_lag_step(probs, scalars.get("tau_motor_s", cls.tau_motor_s),
                              scalars.get("step_internal_s", cls.step_internal_s))
        probs.raise_if_any()
        return dataclasses.replace(cls(), frame=frame, thrust_map=thrust_map, **scalars)

    @classmethod
    def load(cls, path: str | Path) -> QuadrotorParams:
        data = read_json(path)
        return cls.from_dict(vehicle_table(data, "quadrotor", str(path)), source=str(path))

    def to_dict(self) -> dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "thrust_map"}
        d["thrust_map"] = self.thrust_map.to_dict()
        return d


#: every key a flat quadrotor parameter file may hold (what tells a flat file's vehicle)
FLAT_FILE_KEYS = file_keys(QuadrotorParams, FILE_EXTRAS, retired=RENAMED)


def _check_motor_lag_step(probs: ProblemList, tau_s: float, step_s: float) -> None:
    """A motor time constant shorter than the FMU's internal RK4 step: RK4 follows ``tau dT/dt = T_cmd - T``
    wrongly there (decay per step 0.33 for e^-2 = 0.14 at two steps per tau) and diverges below 0.36 of the step."""
    if 0.0 < tau_s < step_s:
        probs.add(f"tau_motor_s = {tau_s:.6g} s is shorter than step_internal_s = {step_s:.6g} s: the FMU's RK4 "
                  f"would not follow the motor (and diverges below {step_s / 2.785:.3g} s); give step_internal_s "
                  f"<= tau_motor_s (allowed 1e-05..0.05 s), or tau_motor_s = 0 for no motor lag")


def _check_map(probs: ProblemList, amap: AnfisMap, idle_us: float, full_us: float) -> None:
    """Problems of a thrust map against the command range of the parameters."""
    if amap.n_inputs != 1:
        probs.add(f"thrust_map has inputs {list(amap.inputs)}; the quadrotor model needs exactly one input, the "
                  "summed motor PWM [us] or a per-motor command (u, u_eff)")
        return
    lo = amap.input_range[0][0] if amap.input_range else 0.0
    if amap.features is not None:
        if amap.inputs[0] not in FEATURE_INPUTS:
            probs.add(f"thrust_map input {amap.inputs[0]!r}; a feature map takes one of {', '.join(FEATURE_INPUTS)}")
        if not lo > 0.0:
            probs.add(f"thrust_map band starts at {lo}; a feature map's band must start above 0 (idle)")
        if not idle_us < full_us:
            probs.add(f"pwm_idle_us = {idle_us}, pwm_full_us = {full_us}; need idle < full")
    elif idle_us * N_MOTORS >= lo:
        probs.add(f"pwm_idle_us = {idle_us} x {N_MOTORS} motors must be below the thrust map's band, which starts "
                  f"at {lo} us summed")


def motor_layout(frame: str) -> tuple[tuple[float, ...], tuple[int, ...]]:
    """Arm angles gamma_i [deg, from body x towards body y] and spin directions of motors 1..4.

    Motor numbering of ArduPilot and PX4. Spin is +1 for clockwise seen from above (along +z body, down),
    -1 for counter-clockwise. Quad X: 1 front-right CCW, 2 rear-left CCW, 3 front-left CW, 4 rear-right CW.
    Quad +: 1 right CCW, 2 left CCW, 3 front CW, 4 back CW.
    """
    if frame == "x":
        return (45.0, 225.0, 315.0, 135.0), (-1, -1, 1, 1)
    if frame == "+":
        return (90.0, 270.0, 0.0, 180.0), (-1, -1, 1, 1)
    raise ValueError(f"frame = {frame!r}; allowed: {', '.join(FRAMES)}")
