"""One C layer, every interface: FMI 2.0 and 3.0, Co-Simulation and Model Exchange, from the same
generated model code; FMPy validates and runs all of them, Model Exchange under CVode agrees with
Co-Simulation, the Python-free C host runs all four, two models' sources link into one program, tunable
parameters take effect mid-run and fixed ones are refused, and huge steps are refused before any work."""

from __future__ import annotations

import ctypes
import math
import os
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from build_fmus import make_model
from fmu_models.fmi import fmuzip, zigcc
from fmu_models.fmi.native_build import FMI3_INCLUDE, FMI_INCLUDE, Interface, model_description
from fmu_models.fmi.statemachine import MAX_INTERNAL_STEPS

HERE = Path(__file__).resolve().parent
VEHICLES = ("quadrotor", "fixed_wing")
START = {
    "quadrotor": {"pwm_1_us": 1530.0, "pwm_2_us": 1530.0, "pwm_3_us": 1530.0, "pwm_4_us": 1530.0,
                  "init_pos_down_m": -20.0},
    "fixed_wing": {"aileron_rad": 0.0, "elevator_rad": -0.1, "rudder_rad": 0.0, "throttle": 0.6},
}


def fmus_of(version: int, built_fmus: dict[str, Path], fmi3_fmus: dict[str, Path]) -> dict[str, Path]:
    return built_fmus if version == 2 else fmi3_fmus


@pytest.mark.parametrize("name", VEHICLES)
def test_fmpy_validation_has_zero_findings_for_every_interface(name: str, built_fmus: dict[str, Path],
                                                               fmi3_fmus: dict[str, Path], tmp_path: Path) -> None:
    assert validate_fmu(str(built_fmus[name])) == []  # FMI 2.0 CS + ME, the default
    assert validate_fmu(str(fmi3_fmus[name])) == []  # FMI 3.0 CS + ME
    model = make_model(name, None, "defaults")
    for version in (2, 3):
        for kinds in (("cs",), ("me",), ("cs", "me")):
            xml = model_description(model, "{0-0}", "2024-01-01T00:00:00Z", Interface(version, kinds))
            fmu = fmuzip.write_fmu(tmp_path / f"{name}_{version}_{'_'.join(kinds)}.fmu",
                                   {"modelDescription.xml": xml}, 0)
            assert validate_fmu(str(fmu)) == [], (version, kinds)
            md = read_model_description(str(fmu))
            assert (md.coSimulation is not None) == ("cs" in kinds)
            assert (md.modelExchange is not None) == ("me" in kinds)
            assert len(md.derivatives) == (len(model.states) if "me" in kinds else 0)


@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("name", VEHICLES)
def test_model_exchange_under_cvode_agrees_with_co_simulation_over_10_s(
        name: str, version: int, built_fmus: dict[str, Path], fmi3_fmus: dict[str, Path]) -> None:
    """Both converge to the solution of the same equations: with the Co-Simulation RK4 at 0.25 ms (at the
    default 1 ms the largest difference is ~1e-5, a fixed-wing acceleration in the first 10 ms)."""
    fmu = str(fmus_of(version, built_fmus, fmi3_fmus)[name])
    common = {"stop_time": 10.0, "output_interval": 0.01, "start_values": {**START[name], "step_internal_s": 2.5e-4}}
    cs = simulate_fmu(fmu, fmi_type="CoSimulation", step_size=0.001, **common)
    me = simulate_fmu(fmu, fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-10, **common)
    names = [n for n in cs.dtype.names if n != "time" and cs[n].dtype.kind == "f"]
    assert len(cs) == len(me) == 1001 and len(names) > 15
    a = np.column_stack([cs[n] for n in names])
    b = np.column_stack([me[n] for n in names])
    assert np.all(np.isfinite(a)) and np.ptp(a, axis=0).max() > 1.0  # it flew
    np.testing.assert_allclose(b, a, rtol=1e-6, atol=1e-6)


def compile_host(folder: Path) -> Path:
    """tests/fakes/native_host.c compiled into ``folder`` (no Python in the program)."""
    exe = folder / "native_host"
    cmd = [*zigcc.zig_cc(), "-target", "x86_64-linux-gnu", "-O2", f"-I{FMI_INCLUDE}", f"-I{FMI3_INCLUDE}", "-o",
           str(exe), str(HERE.parents[1] / "fakes" / "native_host.c"), "-ldl"]
    subprocess.run(cmd, check=True, capture_output=True)
    return exe


@pytest.fixture(scope="module")
def c_host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return compile_host(tmp_path_factory.mktemp("host"))


def run_host(c_host: Path, fmu: Path, mode: str, steps: int, h: float, tmp: Path) -> tuple[np.ndarray, list[int]]:
    md = read_model_description(str(fmu))
    d = Path(extract(str(fmu), unzipdir=str(tmp / mode)))
    var = {v.name: v for v in md.modelVariables}
    plat = zigcc.host_platform()
    lib = d / "binaries" / (plat.fmi_name if mode[0] == "2" else plat.fmi3_name) / f"{fmu.stem}{plat.suffix}"
    outputs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type in ("Real", "Float64")]
    token = md.guid if mode[0] == "2" else md.instantiationToken
    # the host sets these before every step: inputs only (init_* parameters are fixed after initialisation)
    start = ",".join(f"{var[k].valueReference}={v}" for k, v in START[fmu.stem].items() if not k.startswith("init_"))
    csv = tmp / f"{mode}.csv"
    proc = subprocess.run([str(c_host), str(lib), token, "", str(steps), str(h), start, ",".join(map(str, outputs)),
                           str(csv), "1", mode, str(len(md.derivatives))],
                          capture_output=True, text=True, timeout=300, env={"PATH": os.environ.get("PATH", "")})
    assert proc.returncode == 0, proc.stderr
    return np.loadtxt(csv, delimiter=","), outputs


@pytest.mark.parametrize("name", VEHICLES)
def test_c_host_runs_fmi2_and_fmi3_co_simulation_and_model_exchange(
        name: str, built_fmus: dict[str, Path], fmi3_fmus: dict[str, Path], c_host: Path, tmp_path: Path) -> None:
    steps, h = 2000, 0.001
    runs = {}
    for mode in ("2cs", "2me", "3cs", "3me"):
        fmu = fmus_of(int(mode[0]), built_fmus, fmi3_fmus)[name]
        runs[mode], outputs = run_host(c_host, fmu, mode, steps, h, tmp_path)
        assert runs[mode].shape == (steps, len(outputs) + 1) and np.all(np.isfinite(runs[mode]))
    np.testing.assert_array_equal(runs["3cs"], runs["2cs"])  # the same C layer and model code
    np.testing.assert_array_equal(runs["3me"], runs["2me"])
    # the host's own RK4 at the FMU's internal step agrees with the FMU's stepper
    np.testing.assert_allclose(runs["2me"], runs["2cs"], rtol=1e-6, atol=1e-6)
    assert np.ptp(runs["2cs"][:, 1:], axis=0).max() > 0.1


MAIN_C = r"""
#include <stdio.h>
#include "fmi2FunctionTypes.h"
#define DECLARE(id) \
  fmi2Component id##_fmi2Instantiate(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions*, \
                                     fmi2Boolean, fmi2Boolean); \
  fmi2Status id##_fmi2SetupExperiment(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real); \
  fmi2Status id##_fmi2EnterInitializationMode(fmi2Component); \
  fmi2Status id##_fmi2ExitInitializationMode(fmi2Component); \
  fmi2Status id##_fmi2DoStep(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean); \
  fmi2Status id##_fmi2GetReal(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]); \
  void id##_fmi2FreeInstance(fmi2Component);
DECLARE(quadrotor)
DECLARE(fixed_wing)
static void logger(fmi2ComponentEnvironment e, fmi2String n, fmi2Status s, fmi2String c, fmi2String m, ...) {
  (void)e; (void)n; (void)s; (void)c; fprintf(stderr, "%s\n", m); }
#define RUN(id, guid, vr) { \
  fmi2CallbackFunctions cb = {logger, 0, 0, 0, 0}; \
  fmi2Component c = id##_fmi2Instantiate("one", fmi2CoSimulation, guid, NULL, &cb, 0, 0); \
  if (!c) return 1; \
  if (id##_fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) || id##_fmi2EnterInitializationMode(c) || \
      id##_fmi2ExitInitializationMode(c)) return 2; \
  for (int k = 0; k < 100; ++k) if (id##_fmi2DoStep(c, k * 0.01, 0.01, 1)) return 3; \
  fmi2ValueReference r = vr; double y; if (id##_fmi2GetReal(c, &r, 1, &y)) return 4; \
  printf(#id " %.17g\n", y); id##_fmi2FreeInstance(c); }
int main(void) { RUN(quadrotor, QUAD_GUID, QUAD_VR) RUN(fixed_wing, FW_GUID, FW_VR) return 0; }
"""


def test_both_models_sources_link_into_one_program(built_fmus: dict[str, Path], tmp_path: Path) -> None:
    """Every global symbol carries the model identifier: both models' sources/ build one executable."""
    objects, defines = [], []
    for name in VEHICLES:
        d = tmp_path / name
        with zipfile.ZipFile(built_fmus[name]) as z:
            z.extractall(d)
        md = read_model_description(str(built_fmus[name]))
        probe = next(v.valueReference for v in md.modelVariables if v.name == "pos_down_m")
        key = "QUAD" if name == "quadrotor" else "FW"
        defines += [f'-D{key}_GUID="{md.guid}"', f"-D{key}_VR={probe}"]
        for src in ("fmi2Functions.c", f"{name}_model.c", f"{name}_description.c"):
            obj = tmp_path / f"{name}_{src}.o"
            subprocess.run([*zigcc.zig_cc(), "-target", "x86_64-linux-gnu", "-O2", "-c", "-fvisibility=hidden",
                            "-DCASADI_SYMBOL_EXPORT=", f"-DFMI2_FUNCTION_PREFIX={name}_", f"-I{d / 'sources'}",
                            "-o", str(obj), str(d / "sources" / src)], check=True, capture_output=True)
            objects.append(str(obj))
    main = tmp_path / "main.c"
    main.write_text(MAIN_C)
    exe = tmp_path / "both"
    proc = subprocess.run([*zigcc.zig_cc(), "-target", "x86_64-linux-gnu", "-O2", f"-I{FMI_INCLUDE}", *defines,
                           "-o", str(exe), str(main), *objects, "-lm"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr  # no duplicate symbol
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    lines = dict(line.split() for line in run.stdout.splitlines())
    assert set(lines) == set(VEHICLES) and all(math.isfinite(float(v)) for v in lines.values())


# ------------------------------------------------------------------ parameters and steps through FMPy


class Slave:
    """An FMPy FMU2Slave (Co-Simulation) initialised with ``start``; log messages kept."""

    def __init__(self, fmu: Path, **start: float) -> None:
        from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

        self.md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.messages: list[str] = []
        self.cb = fmi2CallbackFunctions()
        self.cb.logger = fmi2CallbackLoggerTYPE(lambda env, name, status, cat, msg: self.messages.append(msg.decode()))
        self.s = FMU2Slave(guid=self.md.guid, unzipDirectory=extract(str(fmu)),
                           modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="t")
        self.s.instantiate(callbacks=self.cb)
        self.s.setupExperiment(startTime=0.0)
        self.s.enterInitializationMode()
        self.set(**start)
        self.s.exitInitializationMode()
        self.t = 0.0

    def set(self, **values: float) -> int:
        refs = (ctypes.c_uint * len(values))(*[self.vr[k] for k in values])
        vals = (ctypes.c_double * len(values))(*values.values())
        return self.s.dll.fmi2SetReal(self.s.component, refs, len(values), vals)  # the status, never raised

    def get(self, names: list[str]) -> np.ndarray:
        return np.array(self.s.getReal([self.vr[n] for n in names]))

    def step(self, h: float) -> int:
        status = self.s.dll.fmi2DoStep(self.s.component, self.t, h, 1)
        if status == 0:
            self.t += h
        return status

    def close(self) -> None:
        self.s.fmi2FreeInstance(self.s.component)


def _perturbed(v: object) -> float:
    start = float(v.start)
    new = start * 1.05 if start != 0.0 else 0.05 * (float(v.max) if v.max is not None else 1.0)
    if v.max is not None and new > float(v.max):
        new = start - 0.05 * abs(start or 1.0)
    return new


#: operating points per vehicle: (start values, seconds flown, inputs changed just before the parameters);
#: a parameter must act at one of them (e.g. a motor lag only while the thrust still follows a command)
POINTS = {
    "quadrotor": [
        ({**START["quadrotor"]}, 0.5, {}),
        ({"pwm_1_us": 1100.0, "pwm_2_us": 1100.0, "pwm_3_us": 1100.0, "pwm_4_us": 1100.0}, 0.5, {}),
        ({"init_pos_down_m": -20.0, "pwm_1_us": 1600.0, "pwm_2_us": 1450.0, "pwm_3_us": 1580.0, "pwm_4_us": 1470.0,
          "battery_voltage_V": 10.5}, 0.3, {"pwm_1_us": 1500.0, "pwm_2_us": 1560.0, "pwm_3_us": 1520.0}),
        ({"init_pos_down_m": -20.0, "pwm_1_us": 1950.0, "pwm_2_us": 1950.0, "pwm_3_us": 1950.0, "pwm_4_us": 1950.0},
         0.1, {}),  # above the thrust map's trained band
    ],
    "fixed_wing": [({**START["fixed_wing"]}, 0.5, {}),
                   ({**START["fixed_wing"], "aileron_rad": 0.1, "rudder_rad": -0.05}, 0.3, {"throttle": 0.8})],
}


@pytest.mark.parametrize("name", VEHICLES)
def test_each_tunable_parameter_changed_mid_run_takes_effect(name: str, built_fmus: dict[str, Path]) -> None:
    """Every parameter declared tunable, set while stepping, changes the derivatives or outputs at once."""
    fmu = built_fmus[name]
    md = read_model_description(str(fmu))
    tunable = [v for v in md.modelVariables if v.causality == "parameter" and v.variability == "tunable"]
    watched = [v.name for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    watched += [v.name for v in md.modelVariables if v.name.startswith("der(")]
    effective: set[str] = set()
    known = {v.name for v in md.modelVariables}
    for start, seconds, change in POINTS[name]:
        s = Slave(fmu, **{k: v for k, v in start.items() if k.startswith("init_")})
        s.set(**{k: v for k, v in start.items() if not k.startswith("init_") and k in known})
        for _ in range(round(seconds / 0.01)):
            assert s.step(0.01) == 0
        s.set(**{k: v for k, v in change.items() if k in known})
        base = s.get(watched)
        for v in tunable:
            if v.name == "step_internal_s":
                continue  # changes the integration, not the model: checked by a step below
            assert s.set(**{v.name: _perturbed(v)}) == 0, v.name
            if not np.array_equal(s.get(watched), base):
                effective.add(v.name)
            assert s.set(**{v.name: float(v.start)}) == 0
        np.testing.assert_array_equal(s.get(watched), base)  # restored
        s.close()
    assert {v.name for v in tunable} - {"step_internal_s"} - effective == set()
    assert len(effective) > 10
    # the internal step: a coarser one changes the result of the next step
    a, b = Slave(fmu, **{k: v for k, v in START[name].items() if k.startswith("init_")}), None
    b = Slave(fmu, **{k: v for k, v in START[name].items() if k.startswith("init_")})
    for s, dt in ((a, 0.001), (b, 0.02)):
        s.set(**{k: v for k, v in START[name].items() if not k.startswith("init_")}, step_internal_s=dt)
        assert s.step(0.2) == 0
    assert not np.array_equal(a.get(watched[:5]), b.get(watched[:5]))
    a.close()
    b.close()


@pytest.mark.parametrize("backend", ("native", "python"))
def test_fixed_parameters_are_refused_while_stepping(backend: str, built_fmus: dict[str, Path],
                                                     python_fmus: dict[str, Path]) -> None:
    fmu = (built_fmus if backend == "native" else python_fmus)["quadrotor"]
    s = Slave(fmu, init_pos_down_m=-5.0)  # settable until initialisation ends
    assert s.get(["pos_down_m"])[0] == pytest.approx(-5.0)
    assert s.set(init_pos_down_m=-50.0) == 3 and "init_pos_down_m" in s.messages[-1]
    assert s.set(mass_kg=1.2) == 0  # tunable
    s.close()


@pytest.mark.parametrize("backend", ("native", "python"))
@pytest.mark.parametrize("h", (1e5, 1e9))
def test_a_step_needing_too_many_internal_steps_is_refused_before_any_work(
        backend: str, h: float, built_fmus: dict[str, Path], python_fmus: dict[str, Path]) -> None:
    fmu = (built_fmus if backend == "native" else python_fmus)["quadrotor"]
    s = Slave(fmu, init_pos_down_m=-5.0)
    assert s.step(0.01) == 0
    before = s.get(["pos_down_m", "vel_down_m_s"])
    t0 = time.perf_counter()
    assert s.step(h) == 3
    assert time.perf_counter() - t0 < 5.0  # refused, not run (1e8 RK4 steps would take minutes)
    assert str(MAX_INTERNAL_STEPS) in "".join(s.messages)
    if backend == "native":  # a refused call changes nothing: the instance still steps from where it was
        np.testing.assert_array_equal(s.get(["pos_down_m", "vel_down_m_s"]), before)
        assert s.step(0.01) == 0
    s.close()


def test_a_failed_step_leaves_states_outputs_and_time_as_they_were(built_fmus: dict[str, Path]) -> None:
    fmu = built_fmus["quadrotor"]
    s = Slave(fmu, init_pos_down_m=-5.0)
    names = ["pos_down_m", "vel_down_m_s", "thrust_total_N"]
    for _ in range(10):
        assert s.step(0.01) == 0
    before = s.get(names)
    assert s.set(pwm_1_us=math.nan) == 0
    assert s.step(0.01) == 3 and "pwm_1_us" in s.messages[-1]
    np.testing.assert_array_equal(s.get(names), before)  # diagnostics in the error state: unchanged
    assert s.s.getRealStatus(2) == pytest.approx(0.1)  # fmi2LastSuccessfulTime
    s.close()


def test_outputs_follow_an_input_set_while_stepping_on_both_backends(built_fmus: dict[str, Path],
                                                                     python_fmus: dict[str, Path]) -> None:
    """fmi2SetReal in step-complete: the next fmi2GetReal answers for the new inputs, native and pythonfmu alike."""
    names = ["thrust_total_N", "accel_body_z_m_s2", "pos_down_m"]
    got = {}
    for backend, fmus in (("native", built_fmus), ("python", python_fmus)):
        s = Slave(fmus["quadrotor"], init_pos_down_m=-5.0)
        assert s.set(**{k: v for k, v in START["quadrotor"].items() if k.startswith("pwm")}) == 0
        for _ in range(20):
            assert s.step(0.01) == 0
        before = s.get(names)
        mass = s.get(["mass_kg"])[0]
        assert s.set(mass_kg=2.0 * mass) == 0  # outputs depend on the mass directly (specific force)
        got[backend] = (before, s.get(names))
        s.close()
    for before, after in got.values():
        assert after[1] == pytest.approx(before[1] / 2.0, rel=1e-9)  # same forces, double mass
        assert after[0] == before[0] and after[2] == before[2]  # thrust and position are states: unchanged
    np.testing.assert_allclose(got["native"][1], got["python"][1], rtol=1e-12)


# ------------------------------------------------------------------ FMI 3.0 bad calls, raw ctypes

LOG3 = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)


class Raw3:
    """The FMI 3.0 library of a native FMU through ctypes, with every log message kept."""

    def __init__(self, fmu: Path, tmp: Path) -> None:
        d = Path(extract(str(fmu), unzipdir=str(tmp)))
        self.md = read_model_description(str(fmu))
        plat = zigcc.host_platform()
        self.lib = ctypes.CDLL(str(d / "binaries" / plat.fmi3_name / f"{fmu.stem}{plat.suffix}"))
        self.messages: list[str] = []
        self.log = LOG3(lambda env, status, cat, msg: self.messages.append(msg.decode()))
        v, d_, b = ctypes.c_void_p, ctypes.c_double, ctypes.c_bool
        self.lib.fmi3InstantiateCoSimulation.restype = v
        self.lib.fmi3InstantiateCoSimulation.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p, b, b, b,
                                                         b, v, ctypes.c_size_t, v, LOG3, v]
        self.lib.fmi3InstantiateScheduledExecution.restype = v
        self.lib.fmi3EnterInitializationMode.argtypes = [v, b, d_, d_, b, d_]
        self.lib.fmi3DoStep.argtypes = [v, d_, d_, b, v, v, v, v]
        self.lib.fmi3SetTime.argtypes = [v, d_]

    def new(self, event_mode: bool = False) -> int | None:
        return self.lib.fmi3InstantiateCoSimulation(b"raw3", self.md.instantiationToken.encode(), None, False, False,
                                                    event_mode, False, None, 0, None, self.log, None)

    def step(self, c: int, t: float, h: float) -> int:
        flags = [ctypes.c_bool() for _ in range(3)]
        last = ctypes.c_double()
        return self.lib.fmi3DoStep(c, t, h, True, *[ctypes.byref(f) for f in flags], ctypes.byref(last))

    def last(self) -> str:
        return self.messages[-1] if self.messages else ""


#: calls through pointers the FMU never handed out, in a child process: a crash there is a failed assertion
UNMAPPED_CALLS = """
import ctypes, sys
lib = ctypes.CDLL(sys.argv[1])
prefix = sys.argv[2]
one_arg = [getattr(lib, prefix + f) for f in ("Terminate", "Reset", "ExitInitializationMode")]
for f in one_arg:
    f.argtypes = [ctypes.c_void_p]
free = getattr(lib, prefix + "FreeInstance")
free.argtypes = [ctypes.c_void_p]
if prefix == "fmi2":
    lib.fmi2DoStep.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
codes = []
for address in (0x10, 0x1000, 0xDEAD0000, 2**47 - 8):
    p = ctypes.c_void_p(address)
    if prefix == "fmi2":
        codes.append(lib.fmi2DoStep(p, 0.0, 0.01, 1))
    codes += [f(p) for f in one_arg]
    free(p)
print(sorted(set(codes)))
"""


def test_fmi3_pointers_never_handed_out_are_refused_without_being_read(fmi3_fmus: dict[str, Path],
                                                                       tmp_path: Path) -> None:
    fmu = fmi3_fmus["quadrotor"]
    Raw3(fmu, tmp_path / "q")  # extracts it
    plat = zigcc.host_platform()
    so = tmp_path / "q" / "binaries" / plat.fmi3_name / f"{fmu.stem}{plat.suffix}"
    got = subprocess.run([sys.executable, "-c", UNMAPPED_CALLS, str(so), "fmi3"], capture_output=True, text=True,
                         timeout=60)
    assert got.returncode == 0, got.stderr[-2000:]
    assert got.stdout.strip() == "[3]"


def test_fmi3_rows_that_differ_from_fmi2_as_the_standard_writes_them(fmi3_fmus: dict[str, Path],
                                                                      tmp_path: Path) -> None:
    """FMI 3.0 sections 2.3.2 and 3.2.1, hard-coded here rather than taken from statemachine.FMI3_MASKS: in
    Instantiated the start values of parameters can be read but not outputs; in Event Mode of a Model Exchange
    instance fmi3EnterEventMode and fmi3SetTime are refused, in Continuous-Time Mode both are allowed."""
    q = Raw3(fmi3_fmus["quadrotor"], tmp_path / "q")
    lib, v = q.lib, ctypes.c_void_p
    lib.fmi3InstantiateModelExchange.restype = v
    lib.fmi3InstantiateModelExchange.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_bool,
                                                 ctypes.c_bool, v, LOG3]
    c = v(lib.fmi3InstantiateModelExchange(b"me3", q.md.instantiationToken.encode(), None, False, False, None,
                                           q.log))
    assert c.value
    var = {x.name: x for x in q.md.modelVariables}
    mass, thrust = var["mass_kg"], var["thrust_total_N"]
    out = (ctypes.c_double * 1)()
    assert lib.fmi3GetFloat64(c, (ctypes.c_uint * 1)(mass.valueReference), 1, out, 1) == 0
    assert out[0] == float(mass.start)
    assert lib.fmi3GetFloat64(c, (ctypes.c_uint * 1)(thrust.valueReference), 1, out, 1) == 3
    assert lib.fmi3EnterInitializationMode(c, False, 0.0, 0.0, False, 0.0) == 0
    assert lib.fmi3ExitInitializationMode(c) == 0  # Model Exchange: now in Event Mode
    assert lib.fmi3EnterEventMode(c) == 3 and lib.fmi3SetTime(c, 0.1) == 3
    assert lib.fmi3EnterContinuousTimeMode(c) == 0
    assert lib.fmi3SetTime(c, 0.1) == 0 and lib.fmi3EnterEventMode(c) == 0
    lib.fmi3FreeInstance(c)


def test_fmi3_bad_calls_are_errors_with_a_message_and_the_instance_stays_usable(fmi3_fmus: dict[str, Path],
                                                                               tmp_path: Path) -> None:
    q = Raw3(fmi3_fmus["quadrotor"], tmp_path / "q")
    lib = q.lib
    assert q.new(event_mode=True) is None and "eventModeUsed" in q.last()
    assert lib.fmi3InstantiateScheduledExecution(b"s", q.md.instantiationToken.encode(), None, False, False, None,
                                                 q.log, None, None, None) is None
    c = ctypes.c_void_p(q.new())  # NULL resource path accepted
    assert c.value
    assert q.step(c, 0.0, 0.01) == 3 and "not allowed in state 'instantiated'" in q.last()
    assert lib.fmi3EnterInitializationMode(c, True, math.nan, 0.0, False, 0.0) == 3 and "tolerance" in q.last()
    assert lib.fmi3EnterInitializationMode(c, False, 0.0, 0.0, True, math.inf) == 3 and "stopTime" in q.last()
    assert lib.fmi3EnterInitializationMode(c, True, 1e-6, 0.0, True, 10.0) == 0
    assert lib.fmi3ExitInitializationMode(c) == 0  # Co-Simulation without event mode: Step Mode
    assert lib.fmi3SetTime(c, 1.0) == 3 and "not allowed in state 'step complete'" in q.last()  # an ME function
    assert lib.fmi3EnterConfigurationMode(c) == 3 and "structural parameters" in q.last()
    out = (ctypes.c_double * 2)()
    vr = (ctypes.c_uint * 1)(0)
    assert lib.fmi3GetFloat64(c, vr, 1, out, 2) == 3 and "nValues" in q.last()
    assert lib.fmi3GetInt32(c, vr, 1, out, 1) == 3 and "no variable of this type" in q.last()
    assert q.step(c, 0.0, 1e9) == 3 and str(MAX_INTERNAL_STEPS) in q.last()
    assert q.step(c, 0.0, 0.01) == 0  # refused calls changed nothing
    state = ctypes.c_void_p()
    assert lib.fmi3GetFMUState(c, ctypes.byref(state)) == 0
    size = ctypes.c_size_t()
    assert lib.fmi3SerializedFMUStateSize(c, state, ctypes.byref(size)) == 0
    buf = ctypes.create_string_buffer(size.value)
    assert lib.fmi3SerializeFMUState(c, state, buf, size.value) == 0
    raw = bytearray(buf.raw)
    raw[len(raw) // 2] ^= 0xFF
    damaged = (ctypes.c_ubyte * len(raw))(*raw)
    assert lib.fmi3DeserializeFMUState(c, damaged, len(raw), ctypes.byref(ctypes.c_void_p())) == 3
    assert q.step(c, 0.01, 0.01) == 0
    assert lib.fmi3SetFMUState(c, state) == 0 and q.step(c, 0.01, 0.01) == 0  # back at t = 0.01 s
    assert lib.fmi3Terminate(c) == 0 and lib.fmi3Reset(c) == 0
    lib.fmi3FreeInstance(c)  # frees the FMU state too
