"""Fixed-wing parameters: the Aerosonde set of Beard & McLain (uavbook), plus what paper 001 identifies.

Defaults are read from ``aerosonde.json`` beside this file (a copy of the uavbook's
``parameters/aerosonde_parameters.py``, source cited in the file). Coefficient names follow the book.
The book's set also holds values this model does not use (``REFERENCE_ONLY``): the reference-file reader
:meth:`FixedWingParams.load_reference` drops them with a note, a user parameter file that sets them is refused
with what to do instead.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

from pydantic import Field

from fmu_models.common.params import file_keys, param, read_json, validate_params, vehicle_table
from fmu_models.config import PositiveFiniteFloat

DEFAULTS_FILE = Path(__file__).with_name("aerosonde.json")
_D = json.loads(DEFAULTS_FILE.read_text())
_P = _D["propulsion"]
C = 100.0  #: generous bound on any aerodynamic coefficient (only catches typos and unit mistakes)
log = logging.getLogger(__name__)

#: keys of the published Aerosonde set that are not parameters of this model: key -> why
REFERENCE_ONLY: dict[str, str] = {
    "C_D_0": "the book's parasitic drag of its linear drag model; this model's drag polar uses C_D_p and e_oswald",
    "C_D_alpha": "the book's drag slope of its linear drag model; this model's drag polar uses C_L_alpha and "
                 "e_oswald",
    "epsilon": "a constant of the book's parameter file that its equations (and this model) do not use",
}
#: what a user parameter file that sets a ``REFERENCE_ONLY`` key is told to do
RETIRED: dict[str, str] = {
    "C_D_0": "the drag polar uses C_D_p (parasitic drag) and e_oswald; set C_D_p instead and delete C_D_0",
    "C_D_alpha": "the drag polar's slope comes from C_L_alpha and e_oswald; delete C_D_alpha",
    "epsilon": "the model never used it; delete epsilon",
}


#: informative keys of aerosonde.json (the model uses KQ_N_m_per_A), checked but not stored
FILE_EXTRAS = {"KV_rpm_per_V": (PositiveFiniteFloat, 1.0), "ncells": (Annotated[int, Field(ge=1, le=100)], 1)}
#: sub-tables of a parameter file whose keys are merged into the top level
SECTIONS = ("propulsion",)


def _c(key: str, unit: str, text: str) -> Any:
    return param(_D[key], unit, -C, C, text)


@dataclass(frozen=True)
class FixedWingParams:
    """Aerosonde UAV (Beard & McLain, Small Unmanned Aircraft, 2nd-edition supplement), SI units."""

    mass_kg: float = param(_D["mass_kg"], "kg", 0.1, 1000.0, "vehicle mass")
    Jx_kg_m2: float = param(_D["Jx_kg_m2"], "kg.m2", 1e-4, 1e4, "inertia about body x")
    Jy_kg_m2: float = param(_D["Jy_kg_m2"], "kg.m2", 1e-4, 1e4, "inertia about body y")
    Jz_kg_m2: float = param(_D["Jz_kg_m2"], "kg.m2", 1e-4, 1e4, "inertia about body z")
    Jxz_kg_m2: float = param(_D["Jxz_kg_m2"], "kg.m2", -1e3, 1e3, "product of inertia Jxz (paper 001 identifies it)")
    S_wing_m2: float = param(_D["S_wing_m2"], "m2", 1e-3, 100.0, "wing area")
    b_m: float = param(_D["b_m"], "m", 0.05, 100.0, "wing span")
    c_m: float = param(_D["c_m"], "m", 0.01, 20.0, "mean aerodynamic chord")
    rho_kg_m3: float = param(_D["rho_kg_m3"], "kg/m3", 0.1, 2.0, "air density at home height")
    density_altitude_scaling: float = param(1.0, "1", 0.0, 1.0,
                                            "1: density follows ISA with height above home; 0: constant")
    e_oswald: float = param(_D["e_oswald"], "1", 0.1, 1.5, "Oswald efficiency")
    M_blend: float = param(_D["M_blend"], "1", 1.0, 1000.0, "stall blending sharpness M")
    alpha0_rad: float = param(_D["alpha0_rad"], "rad", 0.05, 1.5, "stall angle of the blending")
    C_L_0: float = _c("C_L_0", "1", "lift coefficient at zero alpha")
    C_m_0: float = _c("C_m_0", "1", "pitch moment coefficient at zero alpha")
    C_L_alpha: float = _c("C_L_alpha", "1/rad", "lift slope")
    C_m_alpha: float = _c("C_m_alpha", "1/rad", "pitch stiffness")
    C_L_q: float = _c("C_L_q", "1/rad", "lift due to pitch rate")
    C_D_q: float = _c("C_D_q", "1/rad", "drag due to pitch rate")
    C_m_q: float = _c("C_m_q", "1/rad", "pitch damping")
    C_L_delta_e: float = _c("C_L_delta_e", "1/rad", "lift due to elevator")
    C_D_delta_e: float = _c("C_D_delta_e", "1/rad", "drag due to elevator")
    C_m_delta_e: float = _c("C_m_delta_e", "1/rad", "pitch moment due to elevator")
    C_D_p: float = _c("C_D_p", "1", "parasitic drag of the polar")
    C_Y_0: float = _c("C_Y_0", "1", "side force at zero")
    C_ell_0: float = _c("C_ell_0", "1", "roll moment at zero")
    C_n_0: float = _c("C_n_0", "1", "yaw moment at zero")
    C_Y_beta: float = _c("C_Y_beta", "1/rad", "side force due to sideslip")
    C_ell_beta: float = _c("C_ell_beta", "1/rad", "dihedral effect")
    C_n_beta: float = _c("C_n_beta", "1/rad", "weathercock stability")
    C_Y_p: float = _c("C_Y_p", "1/rad", "side force due to roll rate")
    C_ell_p: float = _c("C_ell_p", "1/rad", "roll damping")
    C_n_p: float = _c("C_n_p", "1/rad", "yaw due to roll rate")
    C_Y_r: float = _c("C_Y_r", "1/rad", "side force due to yaw rate")
    C_ell_r: float = _c("C_ell_r", "1/rad", "roll due to yaw rate")
    C_n_r: float = _c("C_n_r", "1/rad", "yaw damping")
    C_Y_delta_a: float = _c("C_Y_delta_a", "1/rad", "side force due to aileron")
    C_ell_delta_a: float = _c("C_ell_delta_a", "1/rad", "roll control power")
    C_n_delta_a: float = _c("C_n_delta_a", "1/rad", "adverse yaw")
    C_Y_delta_r: float = _c("C_Y_delta_r", "1/rad", "side force due to rudder")
    C_ell_delta_r: float = _c("C_ell_delta_r", "1/rad", "roll due to rudder")
    C_n_delta_r: float = _c("C_n_delta_r", "1/rad", "yaw control power")
    x_ac_m: float = param(0.0, "m", -5.0, 5.0, "aerodynamic centre ahead of the CG along body x")
    D_prop_m: float = param(_P["D_prop_m"], "m", 0.01, 5.0, "propeller diameter")
    KQ_N_m_per_A: float = param(_P["KQ_N_m_per_A"], "N.m/A", 1e-4, 10.0, "motor torque constant (= KV in SI)")
    R_motor_ohm: float = param(_P["R_motor_ohm"], "ohm", 1e-4, 100.0, "motor resistance")
    i0_A: float = param(_P["i0_A"], "A", 0.0, 100.0, "motor no-load current")
    V_max_V: float = param(_P["V_max_V"], "V", 1.0, 1000.0, "battery voltage at full throttle")
    C_Q2: float = param(_P["C_Q2"], "1", -10.0, 10.0, "propeller torque coefficient, J^2 term")
    C_Q1: float = param(_P["C_Q1"], "1", -10.0, 10.0, "propeller torque coefficient, J term")
    C_Q0: float = param(_P["C_Q0"], "1", 1e-6, 10.0, "propeller torque coefficient, constant")
    C_T2: float = param(_P["C_T2"], "1", -10.0, 10.0, "propeller thrust coefficient, J^2 term")
    C_T1: float = param(_P["C_T1"], "1", -10.0, 10.0, "propeller thrust coefficient, J term")
    C_T0: float = param(_P["C_T0"], "1", -10.0, 10.0, "propeller thrust coefficient, constant")
    wind_north_m_s: float = param(0.0, "m/s", -100.0, 100.0, "constant wind towards north (NED)")
    wind_east_m_s: float = param(0.0, "m/s", -100.0, 100.0, "constant wind towards east (NED)")
    wind_down_m_s: float = param(0.0, "m/s", -100.0, 100.0, "constant wind downwards (NED)")
    ground_mu_roll: float = param(0.03, "1", 0.0, 2.0, "rolling friction of the wheels (body x)")
    ground_mu_side: float = param(0.5, "1", 0.0, 2.0, "side friction of the wheels (body y)")
    step_internal_s: float = param(0.001, "s", 1e-5, 0.05, "largest internal RK4 step")

    @classmethod
    def from_dict(cls, values: dict[str, Any], source: str = "fixed-wing parameters",
                  reference: bool = False) -> FixedWingParams:
        """Defaults overridden by ``values`` (a ``propulsion`` sub-object is flattened); all problems at once.

        ``reference``: ``values`` is a published reference set (``aerosonde.json``), whose ``REFERENCE_ONLY`` keys
        are dropped with a note in the log; elsewhere they are refused with what to do (``RETIRED``).
        """
        if reference:
            dropped = [k for k in REFERENCE_ONLY if k in values]
            if dropped:
                log.info("%s: %s left out (reference values of the published set, not parameters of this model)",
                         source, ", ".join(dropped))
            values = {k: v for k, v in values.items() if k not in REFERENCE_ONLY}
        scalars = validate_params(cls, values, source, extra=FILE_EXTRAS, sections=SECTIONS, retired=RETIRED)
        return dataclasses.replace(cls(), **{k: v for k, v in scalars.items() if k not in FILE_EXTRAS})

    @classmethod
    def load(cls, path: str | Path) -> FixedWingParams:
        """A user parameter file (a ``fixed_wing`` section or a flat set); ``REFERENCE_ONLY`` keys are refused."""
        data = read_json(path)
        return cls.from_dict(vehicle_table(data, "fixed_wing", str(path)), source=str(path))

    @classmethod
    def load_reference(cls, path: str | Path = DEFAULTS_FILE) -> FixedWingParams:
        """A published reference set such as ``aerosonde.json`` (the defaults): ``REFERENCE_ONLY`` keys dropped."""
        data = read_json(path)
        return cls.from_dict(data.get("fixed_wing", data), source=str(path), reference=True)

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    @property
    def aspect_ratio(self) -> float:
        return self.b_m**2 / self.S_wing_m2


#: every key a flat fixed-wing parameter file may hold (what tells a flat file's vehicle)
FLAT_FILE_KEYS = file_keys(FixedWingParams, FILE_EXTRAS, SECTIONS, RETIRED)
