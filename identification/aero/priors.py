"""A-priori values of fixed-wing derivatives: from the airframe's geometry, from the user, and the spread
given to parameters that stay fixed (for the consider covariance).

The geometry estimate uses only what the parameter file holds (wing area ``S``, span ``b``, chord ``c``) and
textbook proportions for what it does not (tail volumes and arms); every formula and assumed proportion is
cited in ``identification/aero/readme.md`` ("Priors"). The standard deviations are wide on purpose: a prior
only steers what the data leave open, and a data-dominated estimate does not feel it.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fmu_models.fixed_wing.params import FixedWingParams

#: tail proportions assumed when the parameter file has no tail geometry (Raymer 2018, Table 6.4, homebuilt
#: and UAV-like light aircraft: horizontal tail volume 0.50, vertical tail volume 0.04; tail arm ~0.4 span)
TAIL_VOLUME_H = 0.50
TAIL_VOLUME_V = 0.04
TAIL_ARM_OVER_SPAN = 0.40
TAIL_ASPECT_H = 4.0
TAIL_ASPECT_V_EFFECTIVE = 2.3  #: geometric 1.5 times the end-plate factor ~1.55 of a fin on a fuselage (DATCOM)
TAIL_EFFICIENCY = 0.9  #: dynamic-pressure ratio eta at the tail (Nelson 1998, sec. 2.4)
#: relative std of each geometry estimate: the tail proportions are guesses, strip theory overestimates roll
#: damping of low-aspect wings, and fuselage side force is left out of C_Y_beta
GEOMETRY_RELATIVE_SD = {"C_ell_p": 0.5, "C_m_q": 0.6, "C_m_alpha": 0.6, "C_n_r": 0.6, "C_n_beta": 0.6,
                        "C_Y_beta": 1.0}
#: std of a fixed parameter that has no prior: this fraction of |value| ...
FIXED_RELATIVE_SD = 0.5
#: ... except the lift slope: the wing geometry predicts it (Helmbold/DATCOM) far better than the damping
#: and cross derivatives, so 20 % is given instead of 50 %
FIXED_RELATIVE_SD_BY_NAME = {"C_L_alpha": 0.2}
#: ... and at least this much, per coefficient family (for parameters that sit at 0 or near it)
FIXED_SD_FLOOR = {"C_ell": 0.005, "C_n": 0.005, "C_Y": 0.05, "C_m": 0.02, "C_L": 0.1, "C_D": 0.01}
#: the aerodynamic coefficients whose fixed values enter the consider covariance
CONSIDERED = ("C_L_0", "C_L_alpha", "C_L_q", "C_L_delta_e", "C_D_p", "C_D_q", "C_D_delta_e", "C_m_0",
              "C_m_alpha", "C_m_q", "C_m_delta_e", "C_Y_0", "C_Y_beta", "C_Y_p", "C_Y_r", "C_Y_delta_a",
              "C_Y_delta_r", "C_ell_0", "C_ell_beta", "C_ell_p", "C_ell_r", "C_ell_delta_a", "C_ell_delta_r",
              "C_n_0", "C_n_beta", "C_n_p", "C_n_r", "C_n_delta_a", "C_n_delta_r")


class PriorError(ValueError):
    """A prior that does not parse or has a non-positive std."""


@dataclass(frozen=True)
class Prior:
    """An a-priori value with its standard deviation and where it comes from."""

    value: float
    sd: float
    source: str

    def as_dict(self) -> dict[str, Any]:
        return {"value": self.value, "sd": self.sd, "source": self.source}


def lift_slope(aspect: float) -> float:
    """Lift-curve slope [1/rad] of an unswept wing (Helmbold; DATCOM 4.1.3.2 with kappa = 1):
    ``2 pi A / (2 + sqrt(A^2 + 4))``."""
    return 2.0 * math.pi * aspect / (2.0 + math.sqrt(aspect * aspect + 4.0))


def geometry_priors(p: FixedWingParams | dict[str, float]) -> dict[str, Prior]:
    """Damping and stability derivatives from the wing geometry and assumed tail proportions (see module doc).

    Formulas (Nelson 1998 ch. 2, 3, 5; Etkin & Reid 1996 ch. 5; DATCOM): wing lift slope ``a_w`` (Helmbold),
    downwash ``dε/dα = 2 a_w / (π A)``; ``C_ell_p = -a_w (1 + 3λ) / (12 (1 + λ))`` (strip theory, λ = 1);
    ``C_m_alpha = -η V_H a_t (1 - dε/dα)`` (c.g. at the wing's aerodynamic centre); ``C_m_q = -2 η V_H a_t
    l_t / c``; ``C_Y_beta = -η a_v S_v / S``; ``C_n_beta = η V_V a_v``; ``C_n_r = -2 η V_V a_v l_v / b``.
    """
    g = p if isinstance(p, dict) else p.to_dict()
    span, area, chord = float(g["b_m"]), float(g["S_wing_m2"]), float(g["c_m"])
    aspect = span ** 2 / area
    a_w, a_t, a_v = lift_slope(aspect), lift_slope(TAIL_ASPECT_H), lift_slope(TAIL_ASPECT_V_EFFECTIVE)
    eta, arm = TAIL_EFFICIENCY, TAIL_ARM_OVER_SPAN * span
    downwash = 2.0 * a_w / (math.pi * aspect)
    sv_over_s = TAIL_VOLUME_V * span / arm
    values = {
        "C_ell_p": -a_w * 4.0 / 24.0,
        "C_m_alpha": -eta * TAIL_VOLUME_H * a_t * (1.0 - downwash),
        "C_m_q": -2.0 * eta * TAIL_VOLUME_H * a_t * arm / chord,
        "C_Y_beta": -eta * a_v * sv_over_s,
        "C_n_beta": eta * TAIL_VOLUME_V * a_v,
        "C_n_r": -2.0 * eta * TAIL_VOLUME_V * a_v * arm / span,
    }
    return {n: Prior(v, GEOMETRY_RELATIVE_SD[n] * abs(v), "geometry") for n, v in values.items()}


def fixed_sd(name: str, value: float) -> float:
    """The std a fixed parameter without a prior gets: ``FIXED_RELATIVE_SD |value|``, at least its floor."""
    family = next((f for f in FIXED_SD_FLOOR if name.startswith(f + "_")), None)
    rel = FIXED_RELATIVE_SD_BY_NAME.get(name, FIXED_RELATIVE_SD)
    return max(rel * abs(value), FIXED_SD_FLOOR.get(family, 0.0) if family else 0.0)


def parse_priors(text: str, known: set[str] | None = None) -> dict[str, Prior]:
    """``name=value:sd,...`` into priors; errors name the item and what is allowed."""
    out = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        name, sep, rest = item.partition("=")
        try:
            value, sd = (float(v) for v in rest.split(":"))
        except ValueError:
            raise PriorError(f"--prior: {item!r} is not name=value:sd") from None
        out[name.strip()] = _checked(name.strip(), value, sd, "--prior", known)
        if not sep:
            raise PriorError(f"--prior: {item!r} is not name=value:sd")
    return out


def load_priors(path: Path, known: set[str] | None = None) -> dict[str, Prior]:
    """A JSON file ``{"C_ell_p": {"value": -0.5, "sd": 0.1}, ...}`` into priors."""
    try:
        raw = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise PriorError(f"{path}: {err}") from None
    if not isinstance(raw, dict):
        raise PriorError(f"{path}: needs an object name -> {{value, sd}}")
    out = {}
    for name, d in raw.items():
        if not (isinstance(d, dict) and set(d) >= {"value", "sd"}):
            raise PriorError(f"{path}: {name}: needs {{\"value\": number, \"sd\": number > 0}}, got {d!r}")
        try:
            out[name] = _checked(name, float(d["value"]), float(d["sd"]), str(path), known)
        except (TypeError, ValueError) as err:
            raise PriorError(f"{path}: {name}: {err}") from None
    return out


def _checked(name: str, value: float, sd: float, where: str, known: set[str] | None) -> Prior:
    if known is not None and name not in known:
        raise PriorError(f"{where}: {name!r} is not a fixed-wing parameter")
    if not (math.isfinite(value) and math.isfinite(sd) and sd > 0):
        raise PriorError(f"{where}: {name}: value {value} and sd {sd} must be finite, sd > 0")
    return Prior(value, sd, "user")
