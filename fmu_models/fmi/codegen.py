"""Generate C for a model's step and init functions with CasADi, and compile it (build time only)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import casadi as ca

from fmu_models.common.model import (
    VehicleModel,
    derivative_function,
    init_function,
    output_function,
    renamed,
    step_function,
)
from fmu_models.fmi.statemachine import MAX_INTERNAL_STEPS


class CompileError(RuntimeError):
    """The C compiler failed on generated code."""


def entry_names(model_name: str) -> dict[str, str]:
    """The global C names of a model's plain-array entry points (prefixed: several models link together)."""
    return {k: f"{model_name}_uavfmu_{k}" for k in ("initialize", "advance", "derivatives", "outputs")}


def _wrapper(model: VehicleModel, funcs: dict[str, ca.Function], prefix: str) -> str:
    """C entry points with plain arrays, so ctypes and the FMI layer call them without CasADi's work vectors.

    ``<id>_uavfmu_advance`` sub-steps a communication step ``h[0]`` in equal RK4 steps no larger than ``h[1]``
    (at most ``MAX_INTERNAL_STEPS``; the FMI layer refuses larger steps first), the outputs only in the last one
    (that step is fused with them, so a single-step call costs what it did before), and returns 0, or i+1 when
    state i leaves its limit or turns NaN, or -(i+1) when output i is not finite; x_out and y are written only
    on success. ``<id>_uavfmu_derivatives`` and ``<id>_uavfmu_outputs`` serve Model Exchange.
    """
    nx, ny = len(model.states), len(model.outputs)
    limits = ", ".join(repr(float(v)) for v in model.state_limits)
    names = entry_names(model.name)

    def work(*keys: str) -> str:
        """Work vectors for the generated functions ``keys`` (sized for the largest)."""
        fs = [funcs[k] for k in keys]
        size = {a: max(1, *(getattr(f, f"sz_{a}")() for f in fs)) for a in ("arg", "res", "iw", "w")}
        return (f"const casadi_real* arg[{size['arg']}]; casadi_real* res[{size['res']}]; "
                f"casadi_int iw[{size['iw']}]; casadi_real w[{size['w']}];")

    return f"""
/* ---- uavfmu entry points (plain arrays; see fmu_models/fmi/native/uavfmu_model.h) ---- */
#include <string.h>
static const double {prefix}_state_limits[{nx}] = {{{limits}}};

int {names["initialize"]}(const double* u, const double* p, double* x0, double* y0) {{
  {work("init")}
  arg[0] = u; arg[1] = p; res[0] = x0; res[1] = y0;
  if ({prefix}_init(arg, res, iw, w, 0)) return -1000000;
  for (int i = 0; i < {nx}; ++i) if (!(x0[i] == x0[i])) return i + 1;
  return 0;
}}

int {names["advance"]}(const double* x, const double* u, const double* p, const double* h,
                   double* x_out, double* y) {{
  {work("step", "step_state")}
  double xa[{nx}], xb[{nx}], yb[{ny}], dt, steps = ceil(h[0] / h[1] - 1e-9);
  long n;
  if (!(steps >= 1.0)) steps = 1.0;
  if (steps > {MAX_INTERNAL_STEPS}.0) return -1000000; /* refused by the FMI layer before; never overflows */
  n = (long)steps;
  dt = h[0] / (double)n;
  memcpy(xa, x, sizeof(xa));
  for (long k = 0; k < n; ++k) {{
    arg[0] = xa; arg[1] = u; arg[2] = p; arg[3] = &dt; res[0] = xb; res[1] = yb;
    if (k + 1 < n ? {prefix}_step_state(arg, res, iw, w, 0) : {prefix}_step(arg, res, iw, w, 0)) return -1000000;
    for (int i = 0; i < {nx}; ++i)
      if (!(fabs(xb[i]) <= {prefix}_state_limits[i])) return i + 1;
    memcpy(xa, xb, sizeof(xa));
  }}
  for (int i = 0; i < {ny}; ++i) if (!isfinite(yb[i])) return -(i + 1);
  memcpy(x_out, xa, sizeof(xa));
  memcpy(y, yb, sizeof(yb));
  return 0;
}}

int {names["derivatives"]}(const double* x, const double* u, const double* p, double* xdot) {{
  {work("derivatives")}
  arg[0] = x; arg[1] = u; arg[2] = p; res[0] = xdot;
  if ({prefix}_derivatives(arg, res, iw, w, 0)) return -1000000;
  for (int i = 0; i < {nx}; ++i) if (!isfinite(xdot[i])) return i + 1;
  return 0;
}}

int {names["outputs"]}(const double* x, const double* u, const double* p, double* y) {{
  {work("outputs")}
  arg[0] = x; arg[1] = u; arg[2] = p; res[0] = y;
  if ({prefix}_outputs(arg, res, iw, w, 0)) return -1000000;
  for (int i = 0; i < {ny}; ++i) if (!isfinite(y[i])) return -(i + 1);
  return 0;
}}
"""


def generate(model: VehicleModel, out_dir: Path) -> dict[str, Path]:
    """Write ``<name>_model.c`` and the serialised ``<name>_step.casadi``/``<name>_init.casadi``."""
    prefix = f"uavfmu_{model.name}"
    step = step_function(model, f"{prefix}_step")
    init = init_function(model, f"{prefix}_init")
    funcs = {"step": step, "step_state": step_function(model, f"{prefix}_step_state", with_outputs=False),
             "init": init, "derivatives": renamed(derivative_function(model), f"{prefix}_derivatives", eliminate=True),
             "outputs": renamed(output_function(model), f"{prefix}_outputs", eliminate=True)}
    out_dir.mkdir(parents=True, exist_ok=True)
    c_name = f"{model.name}_model.c"
    gen = ca.CodeGenerator(c_name, {"with_header": False, "casadi_real": "double", "casadi_int": "long long int"})
    for f in funcs.values():
        gen.add(f)
    gen.generate(str(out_dir) + "/")
    c_file = out_dir / c_name
    with c_file.open("a") as fh:
        fh.write(_wrapper(model, funcs, prefix))
    saved = {}
    for key in ("step", "init", "outputs"):
        saved[key] = out_dir / f"{model.name}_{key}.casadi"
        funcs[key].save(str(saved[key]))
    return {"c": c_file, **saved}


def find_compiler() -> str | None:
    """The machine's C compiler (``$CC`` is honoured by the caller), or None."""
    for cc in ("cc", "gcc", "clang"):
        path = shutil.which(cc)
        if path:
            return path
    return None


def compile_library(c_file: Path, library: Path, compiler: str, extra: list[str] | None = None,
                    optimisation: str = "-O2") -> None:
    """Compile generated C into a shared library; raise ``CompileError`` with the compiler's output."""
    cmd = [compiler, optimisation, "-fPIC", "-shared", "-o", str(library), str(c_file), "-lm", *(extra or [])]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    except OSError as err:  # no such compiler, not executable: the caller's CompileError, not a crash
        raise CompileError(f"C compiler {compiler!r} could not be run: {err}") from None
    if proc.returncode != 0:
        raise CompileError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-4000:]}")
