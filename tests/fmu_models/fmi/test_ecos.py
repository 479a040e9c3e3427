"""Ecos (the ``ecospy`` package, a C++ co-simulation engine; a test extra) runs both vehicles' FMI 2.0 and 3.0
Co-Simulation FMUs, and every Real output after 5 s of flight equals FMPy's on the same FMU, start values and
communication step. Ecos's library needs Debian's ``libtbb12`` (``make test`` installs it when missing); without
the package or the library the tests skip and say which is missing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

VEHICLES = ("quadrotor", "fixed_wing")
#: inputs and start state of a 5 s flight (the quadrotor climbs from 20 m, the plane flies its trim)
START = {
    "quadrotor": {"pwm_1_us": 1530.0, "pwm_2_us": 1530.0, "pwm_3_us": 1530.0, "pwm_4_us": 1530.0,
                  "init_pos_down_m": -20.0},
    "fixed_wing": {"aileron_rad": 0.02, "elevator_rad": -0.1, "rudder_rad": 0.0, "throttle": 0.6},
}
STEP_S = 0.001
STEPS = 5000


def ecospy():
    """The ``ecospy`` module, or a skip naming what is missing (the package, or the ``libtbb12`` its library
    loads at import)."""
    try:
        import ecospy as module
    except ImportError:
        pytest.skip("ecospy (test extra) not installed")
    except OSError as err:  # the package's libecosc.so could not be loaded: libtbb12 missing
        pytest.skip(f"ecospy's library does not load ({err}); Debian's libtbb12 is needed (make test installs it)")
    return module


@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("name", VEHICLES)
def test_ecos_co_simulation_equals_fmpy(name: str, version: int, built_fmus: dict[str, Path],
                                        fmi3_fmus: dict[str, Path]) -> None:
    ecos = ecospy()
    fmu = (built_fmus if version == 2 else fmi3_fmus)[name]
    md = read_model_description(str(fmu))
    assert md.fmiVersion.startswith(str(version)) and md.coSimulation is not None
    outputs = [v.name for v in md.modelVariables if v.causality == "output" and v.type in ("Real", "Float64")]
    structure = ecos.EcosSimulationStructure()
    structure.add_model("uav", str(fmu))
    structure.add_parameter_set("start", {f"uav::{k}": v for k, v in START[name].items()})
    with ecos.EcosSimulation(structure=structure, step_size=STEP_S) as sim:
        assert sim.init(parameter_set="start")
        sim.step(STEPS)
        t_s = sim.get_time()
        got = np.array([sim.get_real(f"uav::{o}") for o in outputs])
        sim.terminate()
    ref = simulate_fmu(str(fmu), fmi_type="CoSimulation", step_size=STEP_S, stop_time=STEPS * STEP_S,
                       output_interval=STEP_S, start_values=START[name])
    want = np.array([ref[o][-1] for o in outputs])
    first = np.array([ref[o][0] for o in outputs])
    assert t_s == pytest.approx(STEPS * STEP_S, abs=1e-9)
    assert len(outputs) > 25 and np.max(np.abs(want - first)) > 0.1  # it moved: the comparison means something
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)  # Ecos sums its time, FMPy multiplies
