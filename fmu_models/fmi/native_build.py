"""Build a native FMU of any ``VehicleModel``: FMI 2.0 or 3.0, Co-Simulation and/or Model Exchange, no Python
needed by the importer.

One C layer serves every interface (in the style of modelica/Reference-FMUs, ``native/``):
- ``uavfmu_core.h``: the instance, the one state machine and argument rules (``uavfmu_states.h``, generated
  from ``statemachine.py``), the co-simulation stepper and the Model Exchange evaluations;
- ``fmi2Functions.c`` / ``fmi3Functions.c``: thin FMI 2.0 / 3.0 front ends;
- ``<name>_model.c``: CasADi-generated C of the model's RK4 step, initial state, derivatives and outputs;
- ``<name>_description.c``: the variable table generated here.
Every global symbol carries the model identifier, so several models' ``sources/`` link into one program.
Value references: inputs, parameters, outputs (as in the pythonfmu backend), then the continuous states and
their derivatives, then (FMI 3.0) ``time``.
"""

from __future__ import annotations

import hashlib
import json
import tempfile
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree as ET

import casadi as ca

from fmu_models.common.model import Variable, VehicleModel, derivative_function, output_function
from fmu_models.fmi import codegen, fmuzip, statemachine, zigcc
from fmu_models.fmi.postprocess import complete_model_description, unit_definitions

NATIVE = Path(__file__).parent / "native"
FMI_INCLUDE = NATIVE / "third_party" / "fmi2"  #: the official FMI 2.0 headers, vendored unchanged
FMI3_INCLUDE = NATIVE / "third_party" / "fmi3"  #: the official FMI 3.0 headers, vendored unchanged
FMI_HEADERS = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")
FMI3_HEADERS = ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")
KINDS = ("cs", "me")
LOG_CATEGORIES = tuple(zip(statemachine.LOG_CATEGORIES, (
    "Log messages with Warning status.", "Log messages with Discard status.", "Log messages with Error status.",
    "Log messages with Fatal status.", "Log all messages."), strict=True))
#: (causality in the C table, modelDescription causality)
C_KIND = {"input": "UAVFMU_INPUT", "parameter": "UAVFMU_PARAMETER", "output": "UAVFMU_OUTPUT",
          "state": "UAVFMU_STATE", "derivative": "UAVFMU_DERIVATIVE", "time": "UAVFMU_TIME"}


@dataclass(frozen=True)
class Interface:
    """What one FMU provides: FMI version 2 or 3, and Co-Simulation ("cs") and/or Model Exchange ("me")."""

    fmi_version: int = 2
    kinds: tuple[str, ...] = KINDS

    def __post_init__(self) -> None:
        if self.fmi_version not in (2, 3):
            raise ValueError(f"fmi_version = {self.fmi_version!r} is not 2 or 3")
        if not self.kinds or any(k not in KINDS for k in self.kinds):
            raise ValueError(f"kinds = {self.kinds!r} must be a non-empty subset of {KINDS}")

    @property
    def front_end(self) -> str:
        return f"fmi{self.fmi_version}Functions.c"


def _c_str(text: str | None) -> str:
    if text is None:
        return "NULL"
    return json.dumps(text, ensure_ascii=True)  # a valid C string literal for printable ASCII and \\uXXXX-free text


def _c_num(v: float | None) -> str:
    return "0.0" if v is None else repr(float(v)).replace("inf", "INFINITY")


def tunable_parameters(model: VehicleModel) -> set[str]:
    """Parameters whose change while simulating takes effect: those the derivatives, outputs or post-step
    correction depend on, and the internal step. The others (e.g. ``init_*``) only shape the initial state:
    they are ``fixed`` (settable until initialisation ends)."""
    x, u, p = model.states.sym("x"), model.inputs.sym("u"), model.params.sym("p")
    # the traced functions (kept per model structure) called on symbols: the same expressions, not traced again
    expr = ca.vertcat(derivative_function(model)(x, u, p), output_function(model)(x, u, p), model.post_step(x, u, p))
    used = ca.which_depends(expr, p, 1, False)
    return {n for n, d in zip(model.params.names, used, strict=True) if d} | {"step_internal_s"}


@dataclass(frozen=True)
class Row:
    """One model variable in value-reference order."""

    kind: str  # input, parameter, output, state, derivative, time
    index: int  # position in u, p, y or x
    var: Variable
    tunable: bool = False


def variables(model: VehicleModel, interface: Interface | None = None) -> list[Row]:
    """Every variable of the FMU in value-reference order (states and derivatives with Model Exchange)."""
    interface = interface or Interface(2, ("cs",))
    tunable = tunable_parameters(model)
    out = [Row("input", i, v) for i, v in enumerate(model.inputs.variables)]
    out += [Row("parameter", i, v, v.name in tunable) for i, v in enumerate(model.params.variables)]
    out += [Row("output", i, v) for i, v in enumerate(model.outputs.variables)]
    if "me" in interface.kinds:
        states = [Variable(f"state.{v.name}", v.unit, f"continuous state: {v.description}")
                  for v in model.states.variables]
        out += [Row("state", i, v) for i, v in enumerate(states)]
        out += [Row("derivative", i, Variable(f"der({v.name})", _per_second(v.unit), f"time derivative of {v.name}"))
                for i, v in enumerate(states)]
    if interface.fmi_version == 3:
        out.append(Row("time", 0, Variable("time", "s", "simulation time")))
    return out


def _per_second(unit: str) -> str:
    """``unit`` per second in the project's unit grammar (``m`` -> ``m/s``, ``m/s`` -> ``m/s2``)."""
    if unit in ("1", ""):
        return "1/s"
    if unit.endswith("/s"):
        return unit + "2"
    return f"{unit}.s-1" if "/" in unit else f"{unit}/s"


def state_nominals(model: VehicleModel) -> list[float]:
    """Nominal magnitude per state (Model Exchange error weights): 1, or the start value when larger."""
    return [max(1.0, abs(float(v.start))) for v in model.states.variables]


def description_c(model: VehicleModel, guid: str, warnings: dict[str, str], interface: Interface | None = None) -> str:
    """C source of ``uavfmu_model`` (uavfmu_model.h) for ``model``."""
    rows = []
    for r in variables(model, interface):
        v = r.var
        rows.append(
            f"    {{{_c_str(v.name)}, {_c_str(v.unit)}, {C_KIND[r.kind]}, {r.index}, {int(v.boolean)}, "
            f"{_c_num(v.start)}, {int(v.min is not None)}, {int(v.max is not None)}, {_c_num(v.min)}, "
            f"{_c_num(v.max)}, {_c_str(warnings.get(v.name) if r.kind == 'output' else None)}, {int(r.tunable)}}},")
    states = model.states.variables
    return "\n".join([
        f"/* Generated by uavfmu (fmu_models/fmi/native_build.py): the model description of {model.name}. */",
        "#include <math.h>",
        "#include <stddef.h>",
        '#include "uavfmu_model.h"',
        "static const uavfmu_variable variables[] = {",
        *rows,
        "};",
        f"static const char* const state_names[] = {{{', '.join(_c_str(v.name) for v in states)}}};",
        f"static const char* const state_units[] = {{{', '.join(_c_str(v.unit) for v in states)}}};",
        f"static const double state_limits[] = {{{', '.join(_c_num(v) for v in model.state_limits)}}};",
        f"static const double state_nominals[] = {{{', '.join(_c_num(v) for v in state_nominals(model))}}};",
        "const uavfmu_model_info uavfmu_model = {",
        f"    {_c_str(model.name)}, {_c_str(guid)}, {len(model.states)}, {len(model.inputs)}, "
        f"{len(model.params)}, {len(model.outputs)},",
        f"    variables, {len(rows)}, state_names, state_units, state_limits, state_nominals, "
        f"{model.params.index['step_internal_s']},",
        "};",
        "",
    ])


def config_h(model: VehicleModel, interface: Interface) -> str:
    """``uavfmu_config.h``: the model identifier (symbol prefix), the FMI version and the interfaces this FMU
    provides."""
    return "\n".join([
        f"/* Generated by uavfmu (fmu_models/fmi/native_build.py): {model.name}, FMI {interface.fmi_version}.0 */",
        "#ifndef UAVFMU_CONFIG_H", "#define UAVFMU_CONFIG_H",
        f"#define UAVFMU_ID {model.name}",
        f"#define UAVFMU_FMI_VERSION {interface.fmi_version}",
        f"#define UAVFMU_HAS_CS {int('cs' in interface.kinds)}",
        f"#define UAVFMU_HAS_ME {int('me' in interface.kinds)}",
        "#endif", ""])


def _variability(r: Row) -> str:
    if r.kind == "parameter":
        return "tunable" if r.tunable else "fixed"
    return "discrete" if r.var.boolean else "continuous"


def _meta(rows: list[Row]) -> dict[str, dict]:
    return {r.var.name: {"unit": r.var.unit, "min": r.var.min, "max": r.var.max, "boolean": r.var.boolean,
                         "description": r.var.description} for r in rows if r.kind != "time"}


def _root(model: VehicleModel, guid: str, date: str, version: str) -> ET.Element:
    key = "guid" if version == "2.0" else "instantiationToken"
    return ET.Element("fmiModelDescription", {
        "fmiVersion": version, "modelName": model.name, key: guid,
        "generationTool": f"uavfmu {fmuzip.package_version()} (native)", "generationDateAndTime": date,
        "variableNamingConvention": "structured", "description": model.description, "author": "uavfmu",
        "license": "BSD-3-Clause", "version": fmuzip.package_version(),
    })


def _categories_experiment_variables(root: ET.Element) -> ET.Element:
    """Append LogCategories and DefaultExperiment (same in FMI 2.0 and 3.0); return a new ModelVariables."""
    cats = ET.SubElement(root, "LogCategories")
    for name, text in LOG_CATEGORIES:
        ET.SubElement(cats, "Category", name=name, description=text)
    ET.SubElement(root, "DefaultExperiment", startTime="0.0", stopTime="10.0", stepSize="0.01")
    return ET.SubElement(root, "ModelVariables")


def model_description(model: VehicleModel, guid: str, date: str, interface: Interface | None = None) -> bytes:
    """modelDescription.xml of the native FMU (inputs, parameters, outputs as in the pythonfmu backend)."""
    interface = interface or Interface(2, ("cs",))
    if interface.fmi_version == 3:
        return _model_description3(model, guid, date, interface)
    rows = variables(model, interface)
    root = _root(model, guid, date, "2.0")
    root.set("numberOfEventIndicators", "0")
    state_caps = {"canGetAndSetFMUstate": "true", "canSerializeFMUstate": "true",
                  "canNotUseMemoryManagementFunctions": "true", "providesDirectionalDerivative": "false",
                  "canBeInstantiatedOnlyOncePerProcess": "false", "needsExecutionTool": "false"}
    if "me" in interface.kinds:
        ET.SubElement(root, "ModelExchange", {"modelIdentifier": model.name,
                                              "completedIntegratorStepNotNeeded": "false", **state_caps})
    if "cs" in interface.kinds:
        ET.SubElement(root, "CoSimulation", {"modelIdentifier": model.name,
                                             "canHandleVariableCommunicationStepSize": "true",
                                             "canInterpolateInputs": "false", **state_caps})
    mv = _categories_experiment_variables(root)
    index = {}
    for vr, r in enumerate(rows):
        causality = {"state": "local", "derivative": "local"}.get(r.kind, r.kind)
        sv = ET.SubElement(mv, "ScalarVariable", name=r.var.name, valueReference=str(vr), causality=causality,
                           variability=_variability(r))
        index[(r.kind, r.index)] = vr + 1
        if r.kind in ("input", "parameter"):
            ET.SubElement(sv, "Real", start=repr(float(r.var.start)))
        elif r.kind == "derivative":
            ET.SubElement(sv, "Real", derivative=str(index[("state", r.index)]))
        else:
            if r.kind == "state":
                sv.set("initial", "calculated")
            ET.SubElement(sv, "Boolean" if r.var.boolean else "Real")
    ms = ET.SubElement(root, "ModelStructure")
    outputs = [index[("output", r.index)] for r in rows if r.kind == "output"]
    derivs = [index[("derivative", r.index)] for r in rows if r.kind == "derivative"]
    for tag, items in (("Outputs", outputs), ("Derivatives", derivs)):
        if items:
            el = ET.SubElement(ms, tag)
            for i in items:
                ET.SubElement(el, "Unknown", index=str(i))
    initial = sorted(outputs + derivs + [index[("state", r.index)] for r in rows if r.kind == "state"])
    return complete_model_description(ET.tostring(root), _meta(rows), initial)


def _model_description3(model: VehicleModel, guid: str, date: str, interface: Interface) -> bytes:
    rows = variables(model, interface)
    root = _root(model, guid, date, "3.0")
    caps = {"modelIdentifier": model.name, "canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
            "providesDirectionalDerivatives": "false", "providesAdjointDerivatives": "false",
            "canBeInstantiatedOnlyOncePerProcess": "false", "needsExecutionTool": "false"}
    if "me" in interface.kinds:
        ET.SubElement(root, "ModelExchange", {**caps, "needsCompletedIntegratorStep": "true"})
    if "cs" in interface.kinds:
        ET.SubElement(root, "CoSimulation", {**caps, "canHandleVariableCommunicationStepSize": "true",
                                             "hasEventMode": "false", "maxOutputDerivativeOrder": "0"})
    units = unit_definitions(_meta(rows))
    if len(units):
        root.append(units)
    mv = _categories_experiment_variables(root)
    vr_of = {}
    for vr, r in enumerate(rows):
        vr_of[(r.kind, r.index)] = vr
        v = r.var
        attrs = {"name": v.name, "valueReference": str(vr),
                 "causality": {"state": "local", "derivative": "local", "time": "independent"}.get(r.kind, r.kind),
                 "variability": _variability(r)}
        if v.description:
            attrs["description"] = v.description
        if r.kind in ("input", "parameter"):
            attrs["start"] = repr(float(v.start))
        if r.kind == "state":
            attrs["initial"] = "calculated"
        if r.kind == "derivative":
            attrs["derivative"] = str(vr_of[("state", r.index)])
        if not v.boolean:
            attrs["unit"] = v.unit
            if v.min is not None:
                attrs["min"] = repr(float(v.min))
            if v.max is not None:
                attrs["max"] = repr(float(v.max))
        ET.SubElement(mv, "Boolean" if v.boolean else "Float64", attrs)
    ms = ET.SubElement(root, "ModelStructure")
    outputs = [vr_of[("output", r.index)] for r in rows if r.kind == "output"]
    derivs = [vr_of[("derivative", r.index)] for r in rows if r.kind == "derivative"]
    states = [vr_of[("state", r.index)] for r in rows if r.kind == "state"]
    for tag, items in (("Output", outputs), ("ContinuousStateDerivative", derivs),
                       ("InitialUnknown", sorted(outputs + derivs + states))):
        for i in items:
            ET.SubElement(ms, tag, valueReference=str(i))
    ET.indent(root, "  ")
    return ('<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n").encode()


def c_sources(model: VehicleModel, interface: Interface) -> list[str]:
    """The C files of ``sources/`` compiled into the library."""
    return [interface.front_end, f"{model.name}_model.c", f"{model.name}_description.c"]


def build_description(model: VehicleModel, interface: Interface) -> bytes:
    """``sources/buildDescription.xml`` (FMI 2.0.4 / FMI 3.0)."""
    files = "\n".join(f'      <SourceFile name="{n}"/>' for n in c_sources(model, interface))
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiBuildDescription fmiVersion="{interface.fmi_version}.0">
  <BuildConfiguration modelIdentifier="{model.name}" description="C11 (atomics); link with the math library (-lm)">
    <SourceFileSet language="C11">
{files}
      <PreprocessorDefinition name="CASADI_SYMBOL_EXPORT" value=""/>
    </SourceFileSet>
    <Library name="m"/>
  </BuildConfiguration>
</fmiBuildDescription>
""".encode()


def native_sources(model: VehicleModel, work: Path, warnings: dict[str, str],
                   interface: Interface | None = None) -> tuple[dict[str, bytes], str]:
    """Every file of ``sources/`` (name -> bytes) and the GUID (a hash of the sources and variables)."""
    interface = interface or Interface()
    files = codegen.generate(model, work)
    model_c = files["c"].read_bytes()
    spec = [(r.kind, r.index, r.var.name, r.var.unit, r.var.start, r.var.min, r.var.max, r.var.boolean,
             r.var.description, r.tunable) for r in variables(model, interface)]
    shared = {n: (NATIVE / n).read_bytes() for n in (interface.front_end, "uavfmu_core.h", "uavfmu_live.h",
                                                   "uavfmu_model.h")}
    digest = hashlib.sha256(model_c + json.dumps([spec, warnings, fmuzip.package_version(),
                                                  interface.fmi_version, interface.kinds]).encode())
    for name in sorted(shared):
        digest.update(shared[name])
    guid = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, f"uavfmu:{model.name}:{digest.hexdigest()}")) + "}"
    headers, folder = (FMI_HEADERS, FMI_INCLUDE) if interface.fmi_version == 2 else (FMI3_HEADERS, FMI3_INCLUDE)
    sources = {
        **shared,
        "uavfmu_states.h": statemachine.header().encode(),
        "uavfmu_config.h": config_h(model, interface).encode(),
        f"{model.name}_model.c": model_c,
        f"{model.name}_description.c": description_c(model, guid, warnings, interface).encode(),
        "buildDescription.xml": build_description(model, interface),
        **{h: (folder / h).read_bytes() for h in headers},
    }
    return sources, guid


@dataclass
class NativeJob:
    """One FMU being built: its sources written to ``src_dir`` and the archive members gathered so far."""

    model: VehicleModel
    interface: Interface
    src_dir: Path
    guid: str
    epoch: int
    files: dict[str, bytes] = field(default_factory=dict)

    def compile(self, plat: zigcc.Platform) -> tuple[str, bytes]:
        """(archive name, bytes) of the library for ``plat``."""
        name = f"{self.model.name}{plat.suffix}"
        srcs = [self.src_dir / n for n in c_sources(self.model, self.interface)]
        lib = zigcc.compile_shared(srcs, [self.src_dir], plat, self.src_dir.parent / plat.fmi_name / name)
        folder = plat.fmi_name if self.interface.fmi_version == 2 else plat.fmi3_name
        return f"binaries/{folder}/{name}", lib.read_bytes()


def prepare(model: VehicleModel, work: Path, *, warnings: dict[str, str] | None = None,
            documentation: Path | None = None, params_file: Path | None = None,
            interface: Interface | None = None) -> NativeJob:
    """Generate the sources and everything but the binaries of one FMU under ``work``."""
    interface = interface or Interface()
    warnings = warnings or {}
    epoch = fmuzip.build_epoch(params_file)
    sources, guid = native_sources(model, work / "gen", warnings, interface)
    src_dir = work / "sources"
    src_dir.mkdir(parents=True)
    for name, data in sources.items():
        (src_dir / name).write_bytes(data)
    job = NativeJob(model, interface, src_dir, guid, epoch, {f"sources/{n}": d for n, d in sources.items()})
    job.files["modelDescription.xml"] = model_description(model, guid, fmuzip.iso_date(epoch), interface)
    if documentation is not None and Path(documentation).exists():
        job.files["documentation/index.md"] = Path(documentation).read_bytes()
    if params_file is not None:
        job.files[fmuzip.EMBEDDED_PARAMS] = fmuzip.embedded_params_bytes(params_file)
    return job


def build_native_fmu(
    model: VehicleModel,
    out_dir: Path,
    *,
    warnings: dict[str, str] | None = None,
    documentation: Path | None = None,
    params_file: Path | None = None,
    platforms: tuple[zigcc.Platform, ...] = zigcc.PLATFORMS,
    interface: Interface | None = None,
    progress: Callable[[str], None] | None = None,
) -> Path:
    """Build ``out_dir/<model.name>.fmu`` (native, reproducible) and return its path.

    ``interface`` defaults to FMI 2.0 Co-Simulation + Model Exchange; ``platforms`` to linux64, win64 and
    darwin64; ``params_file`` dates the build when ``SOURCE_DATE_EPOCH`` is not set. Raises
    ``codegen.CompileError`` when zig is missing or fails. (``fmus.build_fmus`` compiles several in parallel.)
    """
    with tempfile.TemporaryDirectory(prefix=f"uavfmu_native_{model.name}_") as tmp:
        job = prepare(model, Path(tmp), warnings=warnings, documentation=documentation, params_file=params_file,
                      interface=interface)
        for plat in platforms:
            arc, data = job.compile(plat)
            job.files[arc] = data
            if progress:
                progress(f"compiled {arc}")
    return fmuzip.write_fmu(Path(out_dir) / f"{model.name}.fmu", job.files, job.epoch)
