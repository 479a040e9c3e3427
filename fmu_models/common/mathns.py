"""A tiny math namespace so one formula serves numpy arrays and CasADi expressions.

The physics is written once against CasADi (``ca.sin``, ``ca.vertcat`` ...), which accepts floats too.
A few formulas (the ANFIS forward pass) must also run vectorised over thousands of samples inside
identification; they take a namespace ``xp`` from here instead of importing numpy or CasADi directly.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import casadi as ca
import numpy as np

#: plain-float backend (the HIL per-sample path, one value at a time)
PY = SimpleNamespace(exp=math.exp, fabs=math.fabs, fmax=max, fmin=min, where=lambda c, a, b: a if c else b,
                     sqrt=math.sqrt, sin=math.sin, cos=math.cos, atan2=math.atan2, asin=math.asin, name="python")

#: numpy backend: elementwise over arrays of samples.
NP = SimpleNamespace(exp=np.exp, fabs=np.abs, fmax=np.maximum, fmin=np.minimum, where=np.where, sqrt=np.sqrt,
                     sin=np.sin, cos=np.cos, atan2=np.arctan2, asin=np.arcsin, name="numpy")

#: CasADi backend: symbolic (SX/MX) or numeric (DM / float) scalars.
CA = SimpleNamespace(exp=ca.exp, fabs=ca.fabs, fmax=ca.fmax, fmin=ca.fmin, where=ca.if_else, sqrt=ca.sqrt,
                     sin=ca.sin, cos=ca.cos, atan2=ca.atan2, asin=ca.asin, name="casadi")
