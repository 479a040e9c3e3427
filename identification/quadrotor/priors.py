"""An inertia prior from the airframe: mass, arm length, motor and battery masses -> Jx, Jy, Jz with a spread.

Build-up (point masses and simple solids, as in Luukkonen 2011 and Bouabdallah 2007): each motor (with its
propeller and ESC) a point mass on its arm at ``arm_length_m`` and arm angle ``gamma_i``; the battery a solid
box at the centre whose size scales with its mass from a 3S 2200 mAh pack (0.18 kg, 105 x 34 x 24 mm); the rest
of the mass (hub, arms, electronics) a uniform disc of radius half the arm. ``REL_SD`` is the spread given to
each value: the build-up ignores the arms' real mass distribution, payload and wiring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fmu_models.quadrotor.params import motor_layout

#: relative 1-sigma spread of the build-up inertias (the model ignores arm and payload distribution)
REL_SD = 0.35
#: default motor + propeller + ESC mass [kg] (an F450-class 2212 motor with a 10" propeller and a 20 A ESC)
MOTOR_MASS_KG = 0.06
#: default battery mass [kg] (3S 2200 mAh LiPo) and its size [m] (x, y, z)
BATTERY_MASS_KG = 0.18
BATTERY_SIZE_M = (0.105, 0.034, 0.024)


@dataclass(frozen=True)
class InertiaPrior:
    """Prior inertias [kg m^2] with their 1-sigma spread, and the airframe they came from."""

    Jx_kg_m2: float
    Jy_kg_m2: float
    Jz_kg_m2: float
    rel_sd: float
    source: str

    def as_priors(self) -> dict[str, tuple[float, float]]:
        """``{parameter: (mean, sd)}`` for the output-error estimator."""
        return {n: (v, self.rel_sd * v) for n, v in (("Jx_kg_m2", self.Jx_kg_m2), ("Jy_kg_m2", self.Jy_kg_m2),
                                                       ("Jz_kg_m2", self.Jz_kg_m2))}


class PriorError(ValueError):
    """Airframe masses that cannot make a vehicle (named with their values)."""


def airframe_inertia(mass_kg: float, arm_length_m: float, motor_mass_kg: float = MOTOR_MASS_KG,
                     battery_mass_kg: float = BATTERY_MASS_KG, frame: str = "x", rel_sd: float = REL_SD
                     ) -> InertiaPrior:
    """The inertia prior of the build-up in the module docstring."""
    rest = mass_kg - 4 * motor_mass_kg - battery_mass_kg
    if not (mass_kg > 0 and arm_length_m > 0 and motor_mass_kg >= 0 and battery_mass_kg >= 0 and rest >= 0):
        raise PriorError(f"airframe: mass_kg = {mass_kg}, arm_length_m = {arm_length_m}, motor_mass_kg = "
                         f"{motor_mass_kg}, battery_mass_kg = {battery_mass_kg}: need positive mass and arm, and "
                         "4 motors + battery not heavier than the vehicle")
    gamma, _ = motor_layout(frame)
    jx = sum(motor_mass_kg * (arm_length_m * math.sin(math.radians(g))) ** 2 for g in gamma)
    jy = sum(motor_mass_kg * (arm_length_m * math.cos(math.radians(g))) ** 2 for g in gamma)
    jz = 4 * motor_mass_kg * arm_length_m ** 2
    s = (battery_mass_kg / BATTERY_MASS_KG) ** (1.0 / 3.0) if battery_mass_kg > 0 else 0.0
    bx, by, bz = (s * d for d in BATTERY_SIZE_M)
    jx += battery_mass_kg * (by ** 2 + bz ** 2) / 12
    jy += battery_mass_kg * (bx ** 2 + bz ** 2) / 12
    jz += battery_mass_kg * (bx ** 2 + by ** 2) / 12
    r = 0.5 * arm_length_m
    jx += rest * r ** 2 / 4
    jy += rest * r ** 2 / 4
    jz += rest * r ** 2 / 2
    src = (f"airframe build-up: mass {mass_kg:g} kg, arm {arm_length_m:g} m, 4 motors of {motor_mass_kg:g} kg, "
           f"battery {battery_mass_kg:g} kg, {100 * rel_sd:.0f} % spread")
    return InertiaPrior(jx, jy, jz, rel_sd, src)
