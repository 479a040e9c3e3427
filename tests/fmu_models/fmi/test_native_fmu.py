"""Native FMUs: same numbers as the pythonfmu backend, three platforms, no Python needed, every
importer we know runs them, bad calls are fmi2Error, byte-identical rebuilds."""

from __future__ import annotations

import ctypes
import math
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from fmu_models.fmi import zigcc
from fmu_models.fmi.fmus import build_fmus
from tests.fakes.binexports import IMAGE_FILE_MACHINE_AMD64, macho_exports, pe_exports
from tests.fmu_models.fmi.test_fmu_interfaces import UNMAPPED_CALLS, compile_host

HERE = Path(__file__).resolve().parent
VEHICLES = ("quadrotor", "fixed_wing")
#: every Co-Simulation function of FMI 2.0 (fmi2Functions.h)
FMI2_CS_FUNCTIONS = sorted("""
fmi2GetTypesPlatform fmi2GetVersion fmi2SetDebugLogging fmi2Instantiate fmi2FreeInstance fmi2SetupExperiment
fmi2EnterInitializationMode fmi2ExitInitializationMode fmi2Terminate fmi2Reset fmi2GetReal fmi2GetInteger
fmi2GetBoolean fmi2GetString fmi2SetReal fmi2SetInteger fmi2SetBoolean fmi2SetString fmi2GetFMUstate
fmi2SetFMUstate fmi2FreeFMUstate fmi2SerializedFMUstateSize fmi2SerializeFMUstate fmi2DeSerializeFMUstate
fmi2GetDirectionalDerivative fmi2SetRealInputDerivatives fmi2GetRealOutputDerivatives fmi2DoStep fmi2CancelStep
fmi2GetStatus fmi2GetRealStatus fmi2GetIntegerStatus fmi2GetBooleanStatus fmi2GetStringStatus""".split())
#: the Model Exchange functions of FMI 2.0 (the default native FMU is Co-Simulation + Model Exchange)
FMI2_ME_FUNCTIONS = sorted("""
fmi2EnterEventMode fmi2NewDiscreteStates fmi2EnterContinuousTimeMode fmi2CompletedIntegratorStep fmi2SetTime
fmi2SetContinuousStates fmi2GetDerivatives fmi2GetEventIndicators fmi2GetContinuousStates
fmi2GetNominalsOfContinuousStates""".split())
#: flying inputs per vehicle by name; any other input (e.g. a battery voltage) keeps its start value
FLYING = {
    "quadrotor": {"pwm_1_us": 1530.0, "pwm_2_us": 1530.0, "pwm_3_us": 1530.0, "pwm_4_us": 1530.0,
                  "init_pos_down_m": -20.0},
    "fixed_wing": {"aileron_rad": 0.0, "elevator_rad": -0.1, "rudder_rad": 0.0, "throttle": 0.6},
}


class Slave:
    """An FMPy FMU2Slave in step mode, with names resolved from the modelDescription."""

    def __init__(self, fmu: Path, **start: float) -> None:
        self.md = read_model_description(str(fmu))
        self.var = {v.name: v for v in self.md.modelVariables}
        self.s = FMU2Slave(guid=self.md.guid, unzipDirectory=extract(str(fmu)),
                           modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="t")
        self.s.instantiate()
        self.s.setupExperiment(startTime=0.0)
        self.s.enterInitializationMode()
        self.set(**start)
        self.s.exitInitializationMode()
        self.t = 0.0

    def set(self, **values: float) -> None:
        if values:
            self.s.setReal([self.var[k].valueReference for k in values], list(values.values()))

    def outputs(self) -> tuple[list[float], list[bool]]:
        real = [v.valueReference for v in self.md.modelVariables if v.causality == "output" and v.type == "Real"]
        boolean = [v.valueReference for v in self.md.modelVariables if v.causality == "output" and v.type == "Boolean"]
        return self.s.getReal(real), self.s.getBoolean(boolean)

    def step(self, h: float) -> None:
        self.s.doStep(self.t, h)
        self.t += h

    def close(self) -> None:
        self.s.terminate()
        self.s.freeInstance()


def flying(fmu: Path, name: str) -> dict[str, float]:
    names = {v.name for v in read_model_description(str(fmu)).modelVariables}
    return {k: v for k, v in FLYING[name].items() if k in names}


def run_schedule(fmu: Path, name: str, steps: int = 1500, h: float = 0.001) -> np.ndarray:
    """Outputs after each step under time-varying inputs, a tunable change and a state save/restore."""
    base = flying(fmu, name)
    s = Slave(fmu, **{k: v for k, v in base.items() if k.startswith("init_")})
    inputs = {k: v for k, v in base.items() if not k.startswith("init_")}
    rows = []
    saved = None
    for k in range(steps):
        t = k * h
        s.set(**{n: v + (0.02 * abs(v) + 0.01) * math.sin(2 * math.pi * (1.0 + i) * t)
                 for i, (n, v) in enumerate(inputs.items())})
        if k == steps // 3:
            saved = s.s.getFMUstate()
        if k == steps // 2:
            s.set(mass_kg=s.s.getReal([s.var["mass_kg"].valueReference])[0] * 1.1)
        if k == 2 * steps // 3:
            s.s.setFMUstate(saved)
            s.t = (steps // 3) * h
            s.s.freeFMUstate(saved)
        s.step(h)
        real, boolean = s.outputs()
        rows.append([s.t, *real, *map(float, boolean)])
    s.close()
    return np.array(rows)


@pytest.mark.parametrize("name", VEHICLES)
def test_native_and_pythonfmu_backends_agree_to_1e9(name: str, built_fmus: dict[str, Path],
                                                     python_fmus: dict[str, Path]) -> None:
    native = run_schedule(built_fmus[name], name)
    python = run_schedule(python_fmus[name], name)
    assert native.shape == python.shape and native.shape[1] > 20
    assert np.all(np.isfinite(native))
    np.testing.assert_allclose(native, python, rtol=1e-9, atol=0.0)
    assert np.ptp(native[:, 1:], axis=0).max() > 0.0  # the run moved


@pytest.mark.parametrize("name", VEHICLES)
def test_same_variables_as_the_pythonfmu_backend(name: str, built_fmus: dict[str, Path],
                                                 python_fmus: dict[str, Path]) -> None:
    def table(fmu: Path) -> list[tuple]:
        return [(v.name, v.valueReference, v.causality, v.variability, v.type, v.unit, v.description,
                 None if v.start is None else float(v.start), v.min, v.max)
                for v in read_model_description(str(fmu)).modelVariables]

    native, python = table(built_fmus[name]), table(python_fmus[name])
    assert native[: len(python)] == python
    # Model Exchange adds the continuous states and their derivatives after them (calculated locals)
    extra = native[len(python):]
    assert len(extra) % 2 == 0 and extra
    states, derivatives = extra[: len(extra) // 2], extra[len(extra) // 2:]
    assert all(v[0].startswith("state.") and v[2] == "local" for v in states)
    assert [v[0] for v in derivatives] == [f"der({v[0]})" for v in states]
    md = read_model_description(str(built_fmus[name]))
    assert md.modelExchange is not None and len(md.derivatives) == len(states)
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    assert not md.coSimulation.needsExecutionTool
    assert md.version == build_version()


def build_version() -> str:
    from fmu_models.fmi.fmuzip import package_version

    return package_version()


@pytest.mark.parametrize("name", VEHICLES)
def test_validator_zero_findings_and_three_platforms_with_sources(name: str, built_fmus: dict[str, Path]) -> None:
    fmu = built_fmus[name]
    assert validate_fmu(str(fmu)) == []
    with zipfile.ZipFile(fmu) as z:
        members = set(z.namelist())
        for plat in zigcc.PLATFORMS:
            assert f"binaries/{plat.fmi_name}/{name}{plat.suffix}" in members
        for src in ("fmi2Functions.c", "uavfmu_core.h", "uavfmu_live.h", "uavfmu_states.h", "uavfmu_config.h",
                    f"{name}_model.c", f"{name}_description.c", "uavfmu_model.h", "fmi2Functions.h",
                    "buildDescription.xml"):
            assert f"sources/{src}" in members
        assert b'<fmiBuildDescription fmiVersion="2.0">' in z.read("sources/buildDescription.xml")
        assert not any(m.startswith("resources/") and m.endswith(".py") for m in members)  # no Python inside


@pytest.mark.parametrize("name", VEHICLES)
def test_win64_is_a_pe32plus_dll_and_darwin64_a_macho_dylib_exporting_all_fmi2_functions(
        name: str, built_fmus: dict[str, Path]) -> None:
    with zipfile.ZipFile(built_fmus[name]) as z:
        dll = z.read(f"binaries/win64/{name}.dll")
        dylib = z.read(f"binaries/darwin64/{name}.dylib")
    facts, names = pe_exports(dll)
    assert facts == {"machine": IMAGE_FILE_MACHINE_AMD64, "pe32_plus": True, "dll": True}
    assert sorted(names) == sorted(FMI2_CS_FUNCTIONS + FMI2_ME_FUNCTIONS)  # all, and nothing of the model
    facts, names = macho_exports(dylib)
    assert facts == {"cputype": 0x01000007, "dylib": True}
    assert set(FMI2_CS_FUNCTIONS + FMI2_ME_FUNCTIONS) <= set(names)
    assert not {n for n in names if n.startswith(("uavfmu", "casadi"))}


def test_sources_compile_for_this_platform_and_run(built_fmus: dict[str, Path], tmp_path: Path) -> None:
    """An importer compiling sources/ with its own compiler gets the same numbers as the shipped binary."""
    fmu = built_fmus["quadrotor"]
    with zipfile.ZipFile(fmu) as z:
        z.extractall(tmp_path / "x")
    src = tmp_path / "x" / "sources"
    lib = tmp_path / "x" / "binaries" / "linux64" / "quadrotor.so"
    cmd = [*zigcc.zig_cc(), "-target", "x86_64-linux-gnu", "-O2", "-shared", "-fPIC", "-ffp-contract=off",
           "-fvisibility=hidden", "-DCASADI_SYMBOL_EXPORT=", f"-I{src}", "-o", str(lib), str(src / "fmi2Functions.c"),
           str(src / "quadrotor_model.c"), str(src / "quadrotor_description.c"), "-lm"]
    subprocess.run(cmd, check=True, capture_output=True)
    shipped = Slave(fmu, **flying(fmu, "quadrotor"))
    md = shipped.md
    own = FMU2Slave(guid=md.guid, unzipDirectory=str(tmp_path / "x"), modelIdentifier="quadrotor",
                    instanceName="own")
    own.instantiate()
    own.setupExperiment(startTime=0.0)
    own.enterInitializationMode()
    f = flying(fmu, "quadrotor")
    own.setReal([shipped.var[k].valueReference for k in f], list(f.values()))
    own.exitInitializationMode()
    for k in range(200):
        shipped.step(0.005)
        own.doStep(k * 0.005, 0.005)
    out = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    assert own.getReal(out) == shipped.s.getReal(out)
    own.terminate()
    own.freeInstance()
    shipped.close()


@pytest.fixture(scope="module")
def c_host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return compile_host(tmp_path_factory.mktemp("host"))


@pytest.mark.parametrize("name", VEHICLES)
def test_c_host_without_python_flies_10_s_like_fmpy(name: str, built_fmus: dict[str, Path], c_host: Path,
                                                     tmp_path: Path) -> None:
    fmu = built_fmus[name]
    d = Path(extract(str(fmu), unzipdir=str(tmp_path / "fmu")))
    md = read_model_description(str(fmu))
    var = {v.name: v for v in md.modelVariables}
    start = {k: v for k, v in flying(fmu, name).items() if not k.startswith("init_")}  # set before every step
    outputs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    steps, h = 10_000, 0.001
    csv = tmp_path / "host.csv"
    # ldd-free proof of "no Python": the host is a plain C program; it loads only the FMU's library
    proc = subprocess.run(
        [str(c_host), str(d / "binaries" / "linux64" / f"{name}.so"), md.guid, (d / "resources").as_uri(),
         str(steps), str(h), ",".join(f"{var[k].valueReference}={v}" for k, v in start.items()),
         ",".join(map(str, outputs)), str(csv)],
        capture_output=True, text=True, timeout=120, env={"PATH": os.environ.get("PATH", "")})
    assert proc.returncode == 0, proc.stderr
    host = np.loadtxt(csv, delimiter=",")
    assert host.shape == (steps, len(outputs) + 1)
    s = Slave(fmu, **start)  # as the host: everything set in initialisation mode and before every step
    rows = []
    for _ in range(steps):
        s.set(**start)
        s.step(h)
        rows.append([s.t, *s.s.getReal(outputs)])
    s.close()
    np.testing.assert_allclose(host, np.array(rows), rtol=1e-12, atol=1e-12)
    assert host[-1, 0] == pytest.approx(10.0)


@pytest.mark.parametrize("name", VEHICLES)
def test_libcosim_runs_the_native_fmu(name: str, built_fmus: dict[str, Path]) -> None:
    cosim = pytest.importorskip("libcosimpy.CosimExecution", reason="libcosimpy (test extra) not installed")
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.ERROR)
    fmu = built_fmus[name]
    md = read_model_description(str(fmu))
    var = {v.name: v for v in md.modelVariables}
    ex = cosim.CosimExecution.from_step_size(step_size=int(1e6))  # 1 ms in ns
    idx = ex.add_local_slave(local_slave=CosimLocalSlave(fmu_path=str(fmu), instance_name=name))
    obs = CosimObserver.create_last_value()
    ex.add_observer(observer=obs)
    start = flying(fmu, name)
    for k, v in start.items():
        ex.real_initial_value(slave_index=idx, variable_reference=var[k].valueReference, value=v)
    assert ex.simulate_until(target_time=int(2e9))
    probe = "altitude_m" if "altitude_m" in var else next(v.name for v in md.modelVariables
                                                          if v.causality == "output" and v.type == "Real")
    got = obs.last_real_values(slave_index=idx, variable_references=[var[probe].valueReference])[0]
    s = Slave(fmu, **{k: v for k, v in start.items() if k.startswith("init_")})
    for _ in range(2000):
        s.set(**{k: v for k, v in start.items() if not k.startswith("init_")})
        s.step(0.001)
    want = s.s.getReal([var[probe].valueReference])[0]
    s.close()
    assert got == pytest.approx(want, rel=1e-9, abs=1e-9)


def test_two_builds_are_byte_identical_and_dated_from_source_date_epoch(tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    for backend in ("native", "python"):
        a = build_fmus(None, tmp_path / f"{backend}_a", ["quadrotor"], backend=backend).fmus[0]
        b = build_fmus(None, tmp_path / f"{backend}_b", ["quadrotor"], backend=backend).fmus[0]
        assert a.read_bytes() == b.read_bytes(), backend
        md = read_model_description(str(a))
        assert md.generationDateAndTime == "2023-11-14T22:13:20Z" and md.version == build_version()
        with zipfile.ZipFile(a) as z:
            assert {i.date_time for i in z.infolist()} == {(2023, 11, 14, 22, 13, 20)}
            assert z.namelist() == sorted(z.namelist())


# ---------------------------------------------------------------- bad calls, raw ctypes

LOGGER = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)


class Callbacks(ctypes.Structure):
    _fields_ = [("logger", LOGGER), ("allocateMemory", ctypes.c_void_p), ("freeMemory", ctypes.c_void_p),
                ("stepFinished", ctypes.c_void_p), ("componentEnvironment", ctypes.c_void_p)]


class Raw:
    """The linux64 library of a native FMU through ctypes, with every log message kept."""

    def __init__(self, fmu: Path, tmp: Path) -> None:
        d = Path(extract(str(fmu), unzipdir=str(tmp)))
        self.md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.lib = ctypes.CDLL(str(d / "binaries" / "linux64" / f"{self.md.coSimulation.modelIdentifier}.so"))
        self.messages: list[str] = []
        self.logger = LOGGER(lambda env, inst, status, cat, msg: self.messages.append(msg.decode()))
        self.cb = Callbacks(self.logger, None, None, None, None)
        self.lib.fmi2Instantiate.restype = ctypes.c_void_p
        self.lib.fmi2Instantiate.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p,
                                             ctypes.POINTER(Callbacks), ctypes.c_int, ctypes.c_int]
        self.lib.fmi2DoStep.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
        self.lib.fmi2SetupExperiment.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_double,
                                                 ctypes.c_int, ctypes.c_double]

    def new(self) -> int:
        c = self.lib.fmi2Instantiate(b"raw", 1, self.md.guid.encode(), b"", ctypes.byref(self.cb), 0, 0)
        assert c
        return c

    def init(self, c: int) -> None:
        assert self.lib.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == 0
        assert self.lib.fmi2EnterInitializationMode(ctypes.c_void_p(c)) == 0
        assert self.lib.fmi2ExitInitializationMode(ctypes.c_void_p(c)) == 0

    def last(self) -> str:
        return self.messages[-1] if self.messages else ""


def vrs(*v: int) -> ctypes.Array:
    return (ctypes.c_uint * len(v))(*v)


def test_a_function_of_the_other_interface_is_refused_in_initialization_and_terminated(built_fmus: dict[str, Path],
                                                                     tmp_path: Path) -> None:
    """FMI 2.0.4 sections 3.2, 4.2: a Co-Simulation instance of a CS + ME FMU hands out no continuous states or
    derivatives, even in the states where a Model Exchange instance may (initialization, terminated)."""
    q = Raw(built_fmus["quadrotor"], tmp_path / "q")
    lib = q.lib
    nx = q.md.numberOfContinuousStates
    buf = (ctypes.c_double * nx)()
    c = ctypes.c_void_p(q.new())  # Co-Simulation
    assert lib.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == 0 and lib.fmi2EnterInitializationMode(c) == 0
    for fn in ("fmi2GetContinuousStates", "fmi2GetDerivatives", "fmi2GetNominalsOfContinuousStates"):
        assert getattr(lib, fn)(c, buf, nx) == 3 and "a Model Exchange function" in q.last(), fn
    assert lib.fmi2ExitInitializationMode(c) == 0 and lib.fmi2Terminate(c) == 0
    assert lib.fmi2GetContinuousStates(c, buf, nx) == 3 and "instantiated for Co-Simulation" in q.last()
    lib.fmi2FreeInstance(c)
    me = ctypes.c_void_p(lib.fmi2Instantiate(b"me", 0, q.md.guid.encode(), b"", ctypes.byref(q.cb), 0, 0))
    assert me.value and lib.fmi2SetupExperiment(me, 0, 0.0, 0.0, 0, 0.0) == 0
    assert lib.fmi2EnterInitializationMode(me) == 0 and lib.fmi2GetContinuousStates(me, buf, nx) == 0
    assert any(v != 0.0 for v in buf)  # the ME instance still answers
    lib.fmi2FreeInstance(me)


def test_bad_calls_are_fmi2error_with_a_message_and_the_instance_stays_usable(built_fmus: dict[str, Path],
                                                                             tmp_path: Path) -> None:
    q = Raw(built_fmus["quadrotor"], tmp_path / "q")
    fw = Raw(built_fmus["fixed_wing"], tmp_path / "fw")
    c = ctypes.c_void_p(q.new())
    lib = q.lib
    out = (ctypes.c_double * 4)()
    boolean = (ctypes.c_int * 2)()
    assert lib.fmi2DoStep(c, 0.0, 0.01, 1) == 3 and "not allowed in state 'instantiated'" in q.last()
    assert lib.fmi2ExitInitializationMode(c) == 3
    q.init(c.value)
    n = len(q.md.modelVariables)
    assert lib.fmi2GetReal(c, vrs(n + 5), 1, out) == 3 and f"unknown value reference {n + 5}" in q.last()
    assert lib.fmi2GetReal(c, vrs(q.vr["on_ground"]), 1, out) == 3 and "is a Boolean variable" in q.last()
    assert lib.fmi2GetBoolean(c, vrs(q.vr["pos_down_m"]), 1, boolean) == 3 and "is a Real variable" in q.last()
    assert lib.fmi2GetInteger(c, vrs(0), 1, boolean) == 3 and "no variable of this type" in q.last()
    assert lib.fmi2GetReal(c, None, 2, None) == 3 and "NULL" in q.last()
    assert lib.fmi2SetReal(c, vrs(q.vr["pos_down_m"]), 1, out) == 3 and "is an output" in q.last()
    assert lib.fmi2DoStep(c, 0.0, -0.01, 1) == 3 and "must be finite and > 0" in q.last()
    assert lib.fmi2DoStep(c, 0.0, 0.01, 1) == 0
    assert lib.fmi2DoStep(c, 0.0, 0.01, 1) == 3 and "not the last communication point" in q.last()  # repeated
    assert lib.fmi2DoStep(c, 0.5, 0.01, 1) == 3 and "not the last communication point" in q.last()  # gap
    # FMU states: one of another instance or model, a freed one, or garbage is refused without being read
    other = ctypes.c_void_p(fw.new())
    fw.init(other.value)
    foreign = ctypes.c_void_p()
    assert fw.lib.fmi2GetFMUstate(other, ctypes.byref(foreign)) == 0 and foreign.value
    assert lib.fmi2SetFMUstate(c, foreign) == 3 and "not created by this instance" in q.last()
    assert lib.fmi2SetFMUstate(c, ctypes.c_void_p(12345)) == 3
    assert lib.fmi2DoStep(other, 0.0, 0.01, 1) == 3  # the other model's instance: refused, not read
    assert fw.lib.fmi2DoStep(other, 0.0, 0.01, 1) == 0
    assert lib.fmi2DoStep(ctypes.c_void_p(id(q)), 0.0, 0.01, 1) == 3  # not an instance at all: no crash
    mine = ctypes.c_void_p()
    assert lib.fmi2GetFMUstate(c, ctypes.byref(mine)) == 0
    assert lib.fmi2FreeFMUstate(c, ctypes.byref(ctypes.c_void_p(mine.value))) == 0
    assert lib.fmi2SetFMUstate(c, mine) == 3  # freed
    size = ctypes.c_size_t()
    assert lib.fmi2DeSerializeFMUstate(c, b"\0" * 64, 64, ctypes.byref(ctypes.c_void_p())) == 3
    state = ctypes.c_void_p()
    assert lib.fmi2GetFMUstate(c, ctypes.byref(state)) == 0
    assert lib.fmi2SerializedFMUstateSize(c, state, ctypes.byref(size)) == 0
    assert lib.fmi2SerializeFMUstate(c, state, ctypes.create_string_buffer(size.value), size.value - 1) == 3
    assert lib.fmi2Terminate(c) == 0
    assert lib.fmi2DoStep(c, 0.01, 0.01, 1) == 3 and "terminated" in q.last()
    assert lib.fmi2Reset(c) == 0  # usable again
    q.init(c.value)
    assert lib.fmi2DoStep(c, 0.0, 0.01, 1) == 0
    lib.fmi2FreeInstance(c)  # frees the states it handed out too
    fw.lib.fmi2FreeInstance(other)


def test_pointers_never_handed_out_are_refused_without_being_read(built_fmus: dict[str, Path],
                                                                  tmp_path: Path) -> None:
    """Unmapped addresses (never an instance) and a freed instance: fmi2Error, and the process lives (each call
    compares the pointer with the live instances before reading through it)."""
    q = Raw(built_fmus["quadrotor"], tmp_path / "q")
    so = tmp_path / "q" / "binaries" / "linux64" / f"{q.md.coSimulation.modelIdentifier}.so"
    got = subprocess.run([sys.executable, "-c", UNMAPPED_CALLS, str(so), "fmi2"], capture_output=True, text=True,
                         timeout=60)
    assert got.returncode == 0, got.stderr[-2000:]
    assert got.stdout.strip() == "[3]"
    c = ctypes.c_void_p(q.new())
    q.init(c.value)
    q.lib.fmi2FreeInstance(c)
    assert q.lib.fmi2DoStep(c, 0.0, 0.01, 1) == 3 and q.lib.fmi2Terminate(c) == 3  # freed: refused
    q.lib.fmi2FreeInstance(c)  # a second free is ignored


def test_at_most_4096_live_instances_then_a_clear_error(built_fmus: dict[str, Path], tmp_path: Path) -> None:
    q = Raw(built_fmus["quadrotor"], tmp_path / "q")
    live = [q.new() for _ in range(4096)]
    assert q.lib.fmi2Instantiate(b"one too many", 1, q.md.guid.encode(), b"", ctypes.byref(q.cb), 0, 0) is None
    assert "4096 instances" in q.last() and "live already" in q.last()
    q.lib.fmi2FreeInstance(ctypes.c_void_p(live.pop()))
    live.append(q.new())  # a freed slot is taken again
    for c in live:
        q.lib.fmi2FreeInstance(ctypes.c_void_p(c))


def read_rss_kb() -> int:
    return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE") // 1024


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs /proc to read the resident size")
def test_1000_instantiate_free_cycles_grow_the_process_by_less_than_1_mb(built_fmus: dict[str, Path],
                                                                         tmp_path: Path) -> None:
    q = Raw(built_fmus["quadrotor"], tmp_path / "q")
    state = ctypes.c_void_p()

    def cycle() -> None:
        c = ctypes.c_void_p(q.new())
        q.init(c.value)
        q.lib.fmi2DoStep(c, 0.0, 0.01, 1)
        state.value = None
        q.lib.fmi2GetFMUstate(c, ctypes.byref(state))  # left for fmi2FreeInstance to free
        q.lib.fmi2FreeInstance(c)

    for _ in range(50):
        cycle()
    before = read_rss_kb()
    for _ in range(1000):
        cycle()
    assert read_rss_kb() - before < 1024
