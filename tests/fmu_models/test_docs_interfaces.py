"""docs/interfaces.md against the FMUs' variables (the lists modelDescription.xml is written from; no build).

Both directions: every variable name the doc gives exists in the model with the causality the doc says, and
every FMU variable is named in the doc (patterns ``{a,b}`` and ``<j>`` as the doc explains them).
"""

from __future__ import annotations

import itertools
import json
import re
from pathlib import Path

import pytest

from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import DEFAULTS_FILE, REFERENCE_ONLY
from fmu_models.quadrotor.anfis import published_map
from fmu_models.quadrotor.model import QuadrotorModel
from fmu_models.quadrotor.params import QuadrotorParams

DOC = Path(__file__).resolve().parents[2] / "docs" / "interfaces.md"
CAUSALITY = {"input": "inputs", "parameter": "params", "output": "outputs"}
#: names the fixed-wing section gives that are deliberately NOT FMU variables
NOT_VARIABLES = {"propulsion", "KV_rpm_per_V", "ncells", *REFERENCE_ONLY}


def _section(text: str, start: str, stop: str) -> str:
    return text[text.index(start):text.index(stop, text.index(start) + len(start))]


def _names(text: str) -> list[str]:
    """Backticked variable names and patterns (file names, placeholders and prose left out)."""
    return [t for t in re.findall(r"`([^`]+)`", text) if re.fullmatch(r"[A-Za-z][A-Za-z0-9_{},<>]*", t)]


def _regex(pattern: str) -> re.Pattern[str]:
    parts = re.split(r"(\{[^}]*\}|<[a-z]+>)", pattern)
    out = "".join("(" + "|".join(map(re.escape, p[1:-1].split(","))) + ")" if p.startswith("{")
                  else r"\d+" if p.startswith("<") else re.escape(p) for p in parts)
    return re.compile(out)


def _expand(pattern: str) -> list[str]:
    """Each alternative of ``{a,b}`` groups spelled out (``<j>`` placeholders kept)."""
    parts = re.split(r"(\{[^}]*\})", pattern)
    options = [p[1:-1].split(",") if p.startswith("{") else [p] for p in parts]
    return ["".join(c) for c in itertools.product(*options)]


def _variables(*models: object) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {k: set() for k in CAUSALITY.values()}
    for m in models:
        for kind in out:
            out[kind] |= set(getattr(m, kind).names)
    return out


def _quadrotor_models() -> tuple[object, ...]:
    """The default model, one with a first-order generalised-bell map (slope and p variables) and one with a
    per-motor feature map (what identify thrust writes)."""
    d = published_map().to_dict()
    d.update(mf_type="gbell", mf_slope=[[2.0] * len(d["mf_mean"][0])], order=1,
             consequents=[[0.0, *row] for row in d["consequents"]])
    f = {"inputs": ["u"], "mf_mean": [[0.5, 0.7]], "mf_sigma": [[0.2, 0.2]], "order": 1,
         "features": ["x2", "x", "x2_r"], "consequents": [[9.0, 1.0, 0.1], [9.5, 1.0, 0.1]],
         "input_range": [[0.4, 0.8]]}
    return (QuadrotorModel(), QuadrotorModel(QuadrotorParams.from_dict({"thrust_map": d})),
            QuadrotorModel(QuadrotorParams.from_dict({"thrust_map": f, "pwm_idle_us": 1000.0})))


@pytest.fixture(scope="module")
def doc() -> dict[str, str]:
    text = DOC.read_text()
    fmu = _section(text, "## FMU variables", "\n## ")
    return {"common": _section(fmu, "| name |", "\n###"), "quadrotor": _section(fmu, "### Quadrotor", "\n###"),
            "fixed_wing": fmu[fmu.index("### Fixed wing"):]}


def _by_causality(section: str) -> dict[str, list[str]]:
    """Names of a vehicle paragraph split at 'Inputs', 'Outputs add', 'Parameters:'."""
    pieces = re.split(r"\b(Inputs|Outputs add|Parameters:)", section)
    kinds = {"Inputs": "inputs", "Outputs add": "outputs", "Parameters:": "params"}
    return {kinds[k]: _names(body) for k, body in zip(pieces[1::2], pieces[2::2], strict=True)}


def _table(common: str) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {k: [] for k in CAUSALITY.values()}
    for line in common.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 2 and cells[1] in CAUSALITY:
            out[CAUSALITY[cells[1]]] += _names(cells[0])
    return out


def _check_documented_exist(documented: dict[str, list[str]], actual: dict[str, set[str]], where: str) -> None:
    for kind, names in documented.items():
        for name in names:
            if name in NOT_VARIABLES:
                continue
            for one in _expand(name):
                rx = _regex(one)
                assert any(rx.fullmatch(v) for v in actual[kind]), f"{where}: `{one}` is not an FMU {kind[:-1]}"


def _check_all_documented(actual: dict[str, set[str]], documented: dict[str, list[str]], where: str) -> None:
    for kind, names in actual.items():
        rxs = [_regex(n) for n in documented.get(kind, [])]
        missing = sorted(v for v in names if not any(rx.fullmatch(v) for rx in rxs))
        assert not missing, f"{where}: FMU {kind} not in docs/interfaces.md: {missing}"


def _merge(*parts: dict[str, list[str]]) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {k: [] for k in CAUSALITY.values()}
    for p in parts:
        for k, v in p.items():
            out[k] += v
    return out


def test_common_table_names_exist_in_both_fmus_with_their_causality(doc: dict[str, str]) -> None:
    table = _table(doc["common"])
    assert sum(map(len, table.values())) > 30
    _check_documented_exist(table, _variables(*_quadrotor_models()), "common table (quadrotor)")
    _check_documented_exist(table, _variables(FixedWingModel()), "common table (fixed wing)")


def test_quadrotor_section_matches_the_model_both_ways(doc: dict[str, str]) -> None:
    actual = _variables(*_quadrotor_models())
    section = _by_causality(doc["quadrotor"])
    _check_documented_exist(section, actual, "quadrotor section")
    _check_all_documented(actual, _merge(_table(doc["common"]), section), "quadrotor.fmu")


def test_fixed_wing_section_matches_the_model_both_ways(doc: dict[str, str]) -> None:
    actual = _variables(FixedWingModel())
    section = _by_causality(doc["fixed_wing"])
    _check_documented_exist(section, actual, "fixed-wing section")
    raw = json.loads(DEFAULTS_FILE.read_text())
    keys = [k for k in raw if not k.startswith("_") and k != "propulsion"]
    keys += [k for k in raw["propulsion"] if not k.startswith("_")]
    informative = {k for k in keys if k in NOT_VARIABLES}
    assert informative <= set(_names(doc["fixed_wing"])), "the doc must name the aerosonde.json keys it leaves out"
    every = set(actual["inputs"]) | actual["params"] | actual["outputs"]
    assert not informative & every, f"{informative & every} are FMU variables, the doc says they are not"
    from_json = {"params": [k for k in keys if k not in NOT_VARIABLES]}
    _check_documented_exist(from_json, actual, "aerosonde.json keys")
    _check_all_documented(actual, _merge(_table(doc["common"]), section, from_json), "fixed_wing.fmu")


def test_the_pattern_reader_rejects_what_does_not_exist() -> None:
    """The checker itself can fail: the old doc's ANFIS names and a made-up variable are refused."""
    actual = _variables(*_quadrotor_models())
    for wrong in ("anfis_mean_<i>_<j>_us", "anfis_cons_<r>_<k>", "pwm_{1,5}_us"):
        with pytest.raises(AssertionError):
            _check_documented_exist({"params": [wrong]} if "anfis" in wrong else {"inputs": [wrong]}, actual, "x")
