"""Generate C for a model's step and init functions with CasADi, and compile it (build time only)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import casadi as ca

from fmu_models.common.model import VehicleModel, init_function, step_function


class CompileError(RuntimeError):
    """The C compiler failed on generated code."""


def _wrapper(model: VehicleModel, step: ca.Function, init: ca.Function, prefix: str) -> str:
    """C entry points with plain arrays, so ctypes calls them without CasADi's work-vector protocol.

    ``uavfmu_advance`` sub-steps a communication step ``h[0]`` in equal RK4 steps no larger than ``h[1]``
    and returns 0, or i+1 when state i leaves its limit or turns NaN, or -(i+1) when output i is not finite.
    """
    nx, ny = len(model.states), len(model.outputs)
    limits = ", ".join(repr(float(v)) for v in model.state_limits)

    def sz(f: ca.Function) -> tuple[int, int, int, int]:
        return max(1, f.sz_arg()), max(1, f.sz_res()), max(1, f.sz_iw()), max(1, f.sz_w())

    sa, sr, si, sw = sz(step)
    ia, ir, ii, iw = sz(init)
    return f"""
/* ---- uavfmu entry points (plain arrays) ---- */
#include <string.h>
static const double uavfmu_state_limits[{nx}] = {{{limits}}};

int uavfmu_sizes(int* out) {{
  out[0] = {nx}; out[1] = {len(model.inputs)}; out[2] = {len(model.params)}; out[3] = {ny};
  return 0;
}}

int uavfmu_initialize(const double* u, const double* p, double* x0, double* y0) {{
  const casadi_real* arg[{ia}]; casadi_real* res[{ir}]; casadi_int iw[{ii}]; casadi_real w[{iw}];
  arg[0] = u; arg[1] = p; res[0] = x0; res[1] = y0;
  if ({prefix}_init(arg, res, iw, w, 0)) return -1000000;
  for (int i = 0; i < {nx}; ++i) if (!(x0[i] == x0[i])) return i + 1;
  return 0;
}}

int uavfmu_advance(const double* x, const double* u, const double* p, const double* h,
                   double* x_out, double* y) {{
  const casadi_real* arg[{sa}]; casadi_real* res[{sr}]; casadi_int iw[{si}]; casadi_real w[{sw}];
  double xa[{nx}], xb[{nx}], dt;
  int n = (int)ceil(h[0] / h[1] - 1e-9);
  if (n < 1) n = 1;
  dt = h[0] / n;
  memcpy(xa, x, sizeof(xa));
  arg[0] = xa; arg[1] = u; arg[2] = p; arg[3] = &dt; res[0] = xb; res[1] = y;
  for (int k = 0; k < n; ++k) {{
    if ({prefix}_step(arg, res, iw, w, 0)) return -1000000;
    for (int i = 0; i < {nx}; ++i)
      if (!(fabs(xb[i]) <= uavfmu_state_limits[i])) return i + 1;
    memcpy(xa, xb, sizeof(xa));
  }}
  for (int i = 0; i < {ny}; ++i) if (!isfinite(y[i])) return -(i + 1);
  memcpy(x_out, xa, sizeof(xa));
  return 0;
}}
"""


def generate(model: VehicleModel, out_dir: Path) -> dict[str, Path]:
    """Write ``<name>_model.c`` and the serialised ``<name>_step.casadi``/``<name>_init.casadi``."""
    prefix = f"uavfmu_{model.name}"
    step = step_function(model, f"{prefix}_step")
    init = init_function(model, f"{prefix}_init")
    out_dir.mkdir(parents=True, exist_ok=True)
    c_name = f"{model.name}_model.c"
    gen = ca.CodeGenerator(c_name, {"with_header": False, "casadi_real": "double", "casadi_int": "long long int"})
    gen.add(step)
    gen.add(init)
    gen.generate(str(out_dir) + "/")
    c_file = out_dir / c_name
    with c_file.open("a") as fh:
        fh.write(_wrapper(model, step, init, prefix))
    step_file = out_dir / f"{model.name}_step.casadi"
    init_file = out_dir / f"{model.name}_init.casadi"
    step.save(str(step_file))
    init.save(str(init_file))
    return {"c": c_file, "step": step_file, "init": init_file}


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
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise CompileError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-4000:]}")
