"""Complete pythonfmu's modelDescription.xml: units, ranges, InitialUnknowns.

pythonfmu's ``Real`` carries no unit and its ModelStructure has no InitialUnknowns; FMPy's validator
flags both. This rewrites modelDescription.xml inside the .fmu from the model's own variable lists.
"""

from __future__ import annotations

import hashlib
import uuid
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from fmu_models.fmi import fmuzip
from fmu_models.fmi.units import BASES, parse_unit


def _fmt(v: float) -> str:
    return repr(float(v))


def unit_definitions(variables: dict[str, dict[str, Any]]) -> ET.Element:
    """``<UnitDefinitions>`` of every unit the (non-Boolean) ``variables`` use, with SI base exponents."""
    units = sorted({v["unit"] for v in variables.values() if v.get("unit") and not v.get("boolean")})
    unit_defs = ET.Element("UnitDefinitions")
    for u in units:
        exps, factor = parse_unit(u)
        el = ET.SubElement(unit_defs, "Unit", name=u)
        attrs = {k: str(exps[k]) for k in BASES if k in exps}
        if factor != 1.0:
            attrs["factor"] = _fmt(factor)
        ET.SubElement(el, "BaseUnit", attrs)
    return unit_defs


def complete_model_description(xml_text: bytes, variables: dict[str, dict[str, Any]],
                               initial_unknowns: list[int] | None = None) -> bytes:
    """Return ``xml_text`` (FMI 2.0) with unit definitions, per-variable unit/min/max and InitialUnknowns
    (``initial_unknowns``: 1-based variable indices, default the outputs)."""
    root = ET.fromstring(xml_text)
    # UnitDefinitions goes right after CoSimulation/ModelExchange and before LogCategories (FMI 2.0 order)
    children = list(root)
    pos = max(i for i, c in enumerate(children) if c.tag in ("CoSimulation", "ModelExchange")) + 1
    root.insert(pos, unit_definitions(variables))

    index_of: dict[str, int] = {}
    for i, sv in enumerate(root.find("ModelVariables"), start=1):
        name = sv.get("name")
        index_of[name] = i
        meta = variables.get(name)
        if meta is None:
            continue
        real = sv.find("Real")
        if real is not None:
            if meta.get("unit"):
                real.set("unit", meta["unit"])
            if meta.get("min") is not None:
                real.set("min", _fmt(meta["min"]))
            if meta.get("max") is not None:
                real.set("max", _fmt(meta["max"]))
        if meta.get("description"):
            sv.set("description", meta["description"])

    structure = root.find("ModelStructure")
    for old in structure.findall("InitialUnknowns"):
        structure.remove(old)
    outputs = structure.find("Outputs")
    if initial_unknowns is None and outputs is not None:
        initial_unknowns = [int(unk.get("index")) for unk in outputs.findall("Unknown")]
    if initial_unknowns:
        init = ET.SubElement(structure, "InitialUnknowns")
        for index in sorted(initial_unknowns):
            ET.SubElement(init, "Unknown", index=str(index))
    for el in root.iter():
        el.tail = None
        if el.text is not None and not el.text.strip():
            el.text = None
    ET.indent(root, "  ")
    return ('<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n").encode()


def rewrite_fmu(
    fmu: Path, variables: dict[str, dict[str, Any]], files: dict[str, bytes] | None = None, epoch: int | None = None,
    guid_files: Callable[[str], dict[str, bytes]] | None = None,
) -> None:
    """Complete modelDescription.xml in the ``fmu`` zip; add or replace ``files`` (archive name -> bytes), then
    the files ``guid_files(guid)`` makes for the final GUID (a binary that checks it: derived from the rest,
    so left out of the hash).

    The archive is rewritten reproducibly (``fmuzip.write_fmu``): ``generationDateAndTime`` from ``epoch``
    (default ``fmuzip.build_epoch()``) and a GUID hashed from the FMU's contents replace pythonfmu's clock
    time and random GUID, so two builds of the same sources and parameters are byte-identical.
    """
    epoch = fmuzip.build_epoch() if epoch is None else epoch
    with zipfile.ZipFile(fmu) as zin:
        members = {item.filename: zin.read(item.filename) for item in zin.infolist()}
    members.update(files or {})
    root = ET.fromstring(complete_model_description(members["modelDescription.xml"], variables))
    root.set("generationDateAndTime", fmuzip.iso_date(epoch))
    root.set("version", fmuzip.package_version())
    root.set("guid", "")
    digest = hashlib.sha256(ET.tostring(root))
    for name in sorted(members):
        if name != "modelDescription.xml":
            digest.update(name.encode() + b"\0" + members[name])
    root.set("guid", "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, f"uavfmu:{digest.hexdigest()}")) + "}")
    members.update(guid_files(root.get("guid", "")) if guid_files else {})
    members["modelDescription.xml"] = (
        '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n").encode()
    fmuzip.write_fmu(fmu, members, epoch)
