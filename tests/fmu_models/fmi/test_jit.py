"""The estimator's compiled CasADi functions: cached by the functions' own serialization, so a cached library is
loaded without building the form C is generated from (common subexpressions eliminated) again."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from fmu_models.fmi import jit
from fmu_models.fmi.codegen import find_compiler


def _functions() -> tuple[list[ca.Function], list[ca.Function]]:
    """A function with shared subexpressions, as built and with them eliminated (same name and values)."""
    x = ca.SX.sym("x", 3)
    shared = ca.sin(x[0] * x[1]) + x[2]
    out = ca.vertcat(shared * shared, ca.exp(shared), shared / (1 + x[0] ** 2))
    return [ca.Function("f", [x], [out])], [ca.Function("f", [x], [ca.cse(out)])]


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler: the virtual machine evaluates the functions")
def test_a_cached_library_loads_without_building_its_source_again(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("UAVFMU_CACHE", str(tmp_path))
    raw, eliminated = _functions()
    built = []
    first = jit.compiled(raw, "jit_test", build=lambda: built.append(1) or eliminated)
    assert built == [1] and len(list(tmp_path.glob("jit_test_*.so"))) == 1

    def never() -> list[ca.Function]:
        raise AssertionError("build called although the library is cached")

    again = jit.compiled(_functions()[0], "jit_test", build=never)  # the same function, built anew
    x = np.array([0.3, -1.2, 0.7])
    expected = np.asarray(raw[0](x)).ravel()
    for f in (first[0], again[0]):
        np.testing.assert_allclose(np.asarray(f(x)).ravel(), expected, rtol=1e-14)
    # another function is another library, and a build that renames the function is refused
    y = ca.SX.sym("x", 3)
    other = [ca.Function("f", [y], [ca.vertcat(y[0], y[1], 2 * y[2])])]
    with pytest.raises(ValueError, match="build gave"):
        jit.compiled(other, "jit_test", build=lambda: [ca.Function("g", [y], [y])])
    assert len(list(tmp_path.glob("jit_test_*.so"))) == 1
