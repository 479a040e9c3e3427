"""Property test of every config file type: wrong-typed values are refused.

For each file type a valid document is written to disk and loaded through the project's own loader (a
positive control: it must load). Hypothesis then replaces one field with a value of the wrong kind - a
boolean, a string, NaN, +-inf, a negative number where only positive values make sense, a list, a nested
table - or adds an unknown key, writes the file (JSON or TOML, as users do) and loads it again. The loader
must raise :class:`fmu_models.config.ConfigError` (or its own subclass of it) whose problem lines are one
line each and name the field; any other exception (a traceback) fails the test.
"""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydantic import Field

from fmu_models.config import ConfigError, Schema, bounded, load_config, range_problems, validate_config

EXAMPLES_PER_FAMILY = 160

# ------------------------------------------------------------------------------------------ bad values
NUMBER, NONNEG, INT, STRING, BOOL, TABLE, CHOICE, PATHS, CHANNEL = (
    "number", "nonneg", "int", "string", "bool", "table", "choice", "paths", "channel")

_lists = st.lists(st.integers(-3, 3), min_size=0, max_size=3)
_tables = st.dictionaries(st.sampled_from(["a", "b", "value"]), st.integers(0, 3), min_size=0, max_size=2)
_non_finite = st.sampled_from([math.nan, math.inf, -math.inf])
_strings = st.one_of(st.text(max_size=8), st.sampled_from(["1.5", "100", "true", "nan"]))
_negative = st.one_of(st.floats(min_value=-1e9, max_value=-1e-3), st.integers(min_value=-10**6, max_value=-1))
_not_number = st.one_of(st.booleans(), _strings, _non_finite, _lists, _tables)

BAD: dict[str, st.SearchStrategy[Any]] = {
    NUMBER: _not_number,
    NONNEG: st.one_of(_not_number, _negative),
    INT: st.one_of(_not_number, _negative, st.floats(0.1, 1e3).filter(lambda v: v != int(v))),
    STRING: st.one_of(st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True), _lists, _tables),
    CHOICE: st.one_of(st.booleans(), st.integers(-5, 5), _non_finite, _lists, _tables,
                      st.sampled_from(["no-such-choice", "", "LOCKSTEP "])),
    BOOL: st.one_of(st.integers(0, 1), st.sampled_from(["true", "yes", ""]), st.floats(allow_nan=True), _lists,
                    _tables),
    TABLE: st.one_of(st.booleans(), st.integers(-5, 5), _strings, _non_finite),
    PATHS: st.one_of(st.booleans(), st.integers(-5, 5), _non_finite, _tables, st.lists(st.integers(), min_size=1,
                                                                                       max_size=2)),
    CHANNEL: st.one_of(st.booleans(), _non_finite, st.floats(0.1, 30.0), _lists, _tables,
                       st.sampled_from([0, -1, 33, 1000])),
}


# ------------------------------------------------------------------------------------------ writers
def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):  # a TOML basic string: JSON escapes, raw non-ASCII, DEL escaped
        return json.dumps(v, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return "{" + ", ".join(f"{json.dumps(str(k))} = {_toml_value(x)}" for k, x in v.items()) + "}"


def write(doc: dict[str, Any], path: Path) -> Path:
    """TOML (inline tables, one top-level key per line) or JSON (NaN/Infinity as Python writes them)."""
    if path.suffix == ".toml":
        path.write_text("".join(f"{json.dumps(k)} = {_toml_value(v)}\n" for k, v in doc.items()))
    else:
        path.write_text(json.dumps(doc))
    return path


# ------------------------------------------------------------------------------------------ families
Path_ = tuple[str | int, ...]


@dataclass(frozen=True)
class Family:
    """One config file type: a valid document, its loader, its fields (path -> kind), tables for unknown keys."""

    name: str
    suffix: str
    base: Callable[[], dict[str, Any]]
    load: Callable[[Path], Any]
    fields: Callable[[], list[tuple[Path_, str]]]
    tables: tuple[Path_, ...]


def _kind_of(field: Any) -> str:
    lo = field.metadata["min"]
    return NONNEG if lo is not None and lo >= 0 else NUMBER


def _quadrotor() -> Family:
    from fmu_models.common.params import numeric_fields
    from fmu_models.quadrotor.anfis import published_map
    from fmu_models.quadrotor.params import QuadrotorParams

    def base() -> dict[str, Any]:
        d = QuadrotorParams().to_dict()
        return {"quadrotor": {k: v for k, v in d.items() if k != "thrust_map"} | {"thrust_map": d["thrust_map"]}}

    def fields() -> list[tuple[Path_, str]]:
        q = ("quadrotor",)
        out = [((*q, f.name), _kind_of(f)) for f in numeric_fields(QuadrotorParams)]
        out += [((*q, "frame"), CHOICE), ((*q, "thrust_map"), TABLE)]
        tm = (*q, "thrust_map")
        n_mf = len(published_map().mf_mean[0])
        out += [((*tm, "mf_mean", 0, j), NUMBER) for j in range(n_mf)]
        out += [((*tm, "mf_sigma", 0, j), NONNEG) for j in range(n_mf)]
        out += [((*tm, "consequents", r, 0), NUMBER) for r in range(n_mf)]
        out += [((*tm, "input_range", 0, 0), NUMBER), ((*tm, "input_range", 0, 1), NUMBER)]
        out += [((*tm, "order"), CHOICE), ((*tm, "mf_type"), CHOICE), ((*tm, "inputs"), TABLE)]
        return out

    return Family("quadrotor parameters", ".json", base, QuadrotorParams.load, fields,
                  (("quadrotor",), ("quadrotor", "thrust_map")))


def _fixed_wing() -> Family:
    from fmu_models.common.params import numeric_fields
    from fmu_models.fixed_wing.params import DEFAULTS_FILE, REFERENCE_ONLY, FixedWingParams

    def base() -> dict[str, Any]:  # a user file: the published set without its reference-only keys
        raw = json.loads(DEFAULTS_FILE.read_text())
        return {"fixed_wing": {k: v for k, v in raw.items() if k not in REFERENCE_ONLY}}

    def fields() -> list[tuple[Path_, str]]:
        prop = set(base()["fixed_wing"]["propulsion"])
        out = [(("fixed_wing", "propulsion", f.name) if f.name in prop else ("fixed_wing", f.name), _kind_of(f))
               for f in numeric_fields(FixedWingParams)]
        return [*out, (("fixed_wing", "propulsion"), TABLE), (("fixed_wing", "propulsion", "ncells"), INT)]

    return Family("fixed-wing parameters", ".json", base, FixedWingParams.load, fields,
                  (("fixed_wing",), ("fixed_wing", "propulsion")))


_CHANNEL = {"min_us": 1100, "trim_us": 1500, "max_us": 1900, "out_min": -0.35, "out_max": 0.35, "reversed": False,
            "deadband_us": 0, "failsafe": 0.0}


def _pwm_mapping() -> Family:
    from fmu_models.signals.pwm_mapping import PwmMapping

    def base() -> dict[str, Any]:
        thr = {"source": 3, "min_us": 1000, "trim_us": 1000, "max_us": 2000, "out_min": 0.0, "out_max": 1.0}
        return {"channels": {"aileron_rad": {"source": 1, **_CHANNEL}, "throttle": thr}}

    def fields() -> list[tuple[Path_, str]]:
        ch = ("channels", "aileron_rad")
        kinds = {"source": CHANNEL, "min_us": NONNEG, "trim_us": NONNEG, "max_us": NONNEG, "out_min": NUMBER,
                 "out_max": NUMBER, "reversed": BOOL, "deadband_us": NONNEG, "failsafe": NUMBER}
        return [((*ch, k), kind) for k, kind in kinds.items()] + [(ch, TABLE), (("channels",), TABLE)]

    return Family("PWM mapping", ".toml", base, PwmMapping.load, fields, ((), ("channels", "aileron_rad")))


def _output_map() -> Family:
    from identification.validation import output_map

    def base() -> dict[str, Any]:
        sig = {"log": "roll_rad", "log_unit": "rad", "scale": 1.0, "offset": 0.0, "wrap": False, "max_theil": 0.5,
               "max_rmse": 0.02, "min_skill_persistence": 0.0, "gate": True}
        thrust = {"log": "accel_body_z_m_s2", "scale": -1.0, "scale_by_param": "mass_kg"}
        return {"thresholds": {"max_theil": 0.3, "min_skill_persistence": 0.0},
                "signals": {"roll_rad": sig}, "signals_extra": {"thrust_total_N": thrust}}

    def fields() -> list[tuple[Path_, str]]:
        s = ("signals", "roll_rad")
        kinds = {"log": STRING, "log_unit": STRING, "scale": NUMBER, "offset": NUMBER, "wrap": BOOL,
                 "max_theil": NONNEG, "max_rmse": NONNEG, "min_skill_persistence": NUMBER, "gate": BOOL}
        out = [((*s, k), kind) for k, kind in kinds.items()]
        return [*out, (("thresholds", "max_theil"), NONNEG), (("thresholds", "min_skill_persistence"), NUMBER),
                (("signals_extra", "thrust_total_N", "scale_by_param"), STRING), (s, TABLE), (("thresholds",), TABLE)]

    return Family("output map", ".toml", base, lambda p: output_map.load(p, "quadrotor"), fields,
                  ((), ("thresholds",), ("signals", "roll_rad")))


def _channel_map() -> Family:
    from identification.logs.channel_map import load_channel_map

    def base() -> dict[str, Any]:
        return {"channels": {"motor_1_pwm_us": 3, "motor_2_pwm_us": 4, "throttle_pwm_us": "RCOU.C3"}}

    def fields() -> list[tuple[Path_, str]]:
        return [(("channels", "motor_1_pwm_us"), CHANNEL), (("channels", "throttle_pwm_us"), CHANNEL),
                (("channels",), TABLE)]

    return Family("channel map", ".toml", base, load_channel_map, fields, ((),))


def _hil_config() -> Family:
    from hil_adapter.config import load_hil_config

    def base() -> dict[str, Any]:
        return {"network": {"host": "127.0.0.1", "port": 4560},
                "timing": {"mode": "lockstep", "rate_hz": 250, "busy_poll_us": 500},
                "watchdog": {"timeout_s": 0.5, "mode": "throttle_off"},
                "nmea": {"port": "/dev/null", "baud": 9600, "rate_hz": 5.0},
                "px4": {"rc_channels": [1500, 1500, 1000, 1500], "wing_controls": {"1": 0, "2": 1}},
                "start": {"init_pos_down_m": -10.0},
                "sensors": {"seed": 3, "gps": {"rate_hz": 5.0, "eph_m": 1.0}, "accel": {"noise_std": 0.02}},
                "mapping": {"channels": {"aileron_rad": {"source": 1, **_CHANNEL}}}}

    def fields() -> list[tuple[Path_, str]]:
        return [(("network", "host"), STRING), (("network", "port"), INT), (("timing", "mode"), CHOICE),
                (("timing", "rate_hz"), NONNEG), (("timing", "busy_poll_us"), NONNEG),
                (("watchdog", "timeout_s"), NONNEG), (("watchdog", "mode"), CHOICE), (("nmea", "baud"), INT),
                (("nmea", "rate_hz"), NONNEG), (("network",), TABLE), (("timing",), TABLE),
                (("px4", "rc_channels", 0), INT), (("px4", "wing_controls", "1"), INT),
                (("start", "init_pos_down_m"), NUMBER), (("sensors", "seed"), INT),
                (("sensors", "gps", "rate_hz"), NONNEG), (("sensors", "accel", "noise_std"), NONNEG),
                (("mapping", "channels", "aileron_rad", "source"), CHANNEL),
                (("mapping", "channels", "aileron_rad", "max_us"), NONNEG)]

    return Family("HIL config", ".toml", base, load_hil_config, fields,
                  ((), ("network",), ("timing",), ("sensors", "gps"), ("mapping", "channels", "aileron_rad")))


def _manifest() -> Family:
    from identification.validation.workflow import load_manifest

    def load(path: Path) -> Any:
        return load_manifest(path, {"rate_hz": 50.0})

    def base() -> dict[str, Any]:
        return {"defaults": {"window_s": 10.0, "rate_hz": 50.0, "max_theil": 0.3},
                "job": [{"fmu": "quadrotor.fmu", "log": ["a.bin", "b.bin"], "set": {"mass_kg": 1.2},
                         "window_s": 5.0}]}

    def fields() -> list[tuple[Path_, str]]:
        d, j = ("defaults",), ("job", 0)
        return [((*d, "window_s"), NONNEG), ((*d, "rate_hz"), NONNEG), ((*d, "max_theil"), NONNEG),
                ((*j, "fmu"), PATHS), ((*j, "log"), PATHS), ((*j, "window_s"), NONNEG),
                ((*j, "set", "mass_kg"), NUMBER), ((*j, "set"), TABLE), (d, TABLE)]

    return Family("batch manifest", ".toml", base, load, fields, ((), ("defaults",), ("job", 0)))


FAMILIES: dict[str, Callable[[], Family]] = {
    "quadrotor_params": _quadrotor, "fixed_wing_params": _fixed_wing, "pwm_mapping": _pwm_mapping,
    "output_map": _output_map, "channel_map": _channel_map, "hil_config": _hil_config, "manifest": _manifest,
}
#: wrong documents each family must have refused in its own test (1000 in all, whatever the test order)
MIN_PER_FAMILY = -(-1000 // len(FAMILIES))


# ------------------------------------------------------------------------------------------ the test
def _set(doc: dict[str, Any], path: Path_, value: Any) -> dict[str, Any]:
    doc = copy.deepcopy(doc)
    node: Any = doc
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return doc


def _field_name(path: Path_) -> str:
    return next(str(p) for p in reversed(path) if isinstance(p, str))


@st.composite
def _mutations(draw: st.DrawFn, fam: Family) -> tuple[dict[str, Any], str, str]:
    """(document with one bad field or one unknown key, field name the error must name, description)."""
    doc = fam.base()
    if draw(st.integers(0, 5)) == 0:  # one in six: an unknown key somewhere
        table = draw(st.sampled_from(fam.tables))
        key = "zz_" + draw(st.text("abcdefghij_", min_size=1, max_size=6))
        node: Any = doc
        for k in table:
            node = node[k]
        node[key] = draw(st.one_of(st.integers(-3, 3), _strings, _lists))
        return doc, key, f"unknown key {key!r} in {table}"
    path, kind = draw(st.sampled_from(fam.fields()))
    value = draw(BAD[kind])
    return _set(doc, path, value), _field_name(path), f"{'.'.join(map(str, path))} = {value!r} ({kind})"


def check_rejected(fam: Family, doc: dict[str, Any], field: str, what: str, folder: Path) -> None:
    path = write(doc, folder / f"config{fam.suffix}")
    with pytest.raises(ConfigError) as info:
        fam.load(path)
    problems = info.value.problems
    assert problems, f"{fam.name}: {what}: ConfigError without problems"
    assert all("\n" not in p for p in problems), f"{fam.name}: {what}: a problem spans lines: {problems}"
    assert any(field in p for p in problems), f"{fam.name}: {what}: no problem names {field!r}: {problems}"


@pytest.mark.parametrize("name", list(FAMILIES))
def test_valid_document_loads(name: str, tmp_path: Path) -> None:
    """Positive control: the unmutated document of each family loads, so every rejection below is the mutation."""
    fam = FAMILIES[name]()
    fam.load(write(fam.base(), tmp_path / f"config{fam.suffix}"))


@pytest.mark.parametrize("name", list(FAMILIES))
def test_wrong_values_are_refused_with_a_named_field(name: str, tmp_path_factory: pytest.TempPathFactory) -> None:
    fam = FAMILIES[name]()
    folder = tmp_path_factory.mktemp(name)

    ran = 0

    @settings(max_examples=EXAMPLES_PER_FAMILY, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow])
    @given(_mutations(fam))
    def check(case: tuple[dict[str, Any], str, str]) -> None:
        nonlocal ran
        check_rejected(fam, *case, folder)
        ran += 1

    check()
    print(f"\nconfig schema property test {name}: {ran} wrong documents refused")
    # counted in this test, whatever ran before it: every family refuses its share of >= 1000 documents
    assert ran >= MIN_PER_FAMILY, f"{name}: only {ran} wrong documents were tried"


# ------------------------------------------------------------------ the messages themselves, by hand
class _Inner(Schema):
    gain: float = Field(1.0, gt=0.0, le=5.0)
    name: str = "x"


class _Doc(Schema):
    rate_hz: float = Field(50.0, ge=1.0, lt=100.0)
    count: int = Field(3, ge=0)
    flag: bool = False
    inner: _Inner = _Inner()
    table: dict[str, _Inner] = Field(default_factory=dict)
    items: list[Annotated[float, Field(ge=-1.0, le=1.0)]] = Field(default_factory=list)
    pair: tuple[int, Annotated[float, Field(ge=2.0)]] = (0, 2.0)
    need: float


def _problems(data: dict[str, Any]) -> list[str]:
    with pytest.raises(ConfigError) as err:
        validate_config(data, _Doc, "doc.toml")
    assert str(err.value).startswith(f"doc.toml: {len(err.value.problems)} problem(s):\n  - ")
    return err.value.problems


def test_each_problem_names_field_value_and_whole_range() -> None:
    assert _problems({"need": 1.0, "rate_hz": 0.5}) == [
        "field rate_hz = 0.5: Input should be greater than or equal to 1 (allowed: >= 1 and < 100)"]
    assert _problems({"need": 1.0, "rate_hz": float("nan")}) == [
        "field rate_hz = nan: not finite (allowed: a finite number >= 1 and < 100)"]
    assert _problems({"need": 1.0, "inner": {"gain": 0.0}}) == [
        "field inner.gain = 0.0: Input should be greater than 0 (allowed: > 0 and <= 5)"]
    assert _problems({"need": 1.0, "table": {"a": {"gain": 9.0}}}) == [
        "field table.a.gain = 9.0: Input should be less than or equal to 5 (allowed: > 0 and <= 5)"]
    assert _problems({"need": 1.0, "items": [0.0, 2.0]}) == [
        "field items.1 = 2.0: Input should be less than or equal to 1 (allowed: >= -1 and <= 1)"]
    assert _problems({"need": 1.0, "pair": (0, 1.0)}) == [
        "field pair.1 = 1.0: Input should be greater than or equal to 2 (allowed: >= 2)"]
    assert _problems({"need": 1.0, "count": -2}) == [
        "field count = -2: Input should be greater than or equal to 0 (allowed: >= 0)"]


def test_types_missing_and_unknown_keys() -> None:
    got = _problems({"rate_hz": "fast", "flag": 1, "inner": {"name": 3, "gian": 2.0}, "extra": 1})
    assert "field need: missing (required)" in got
    assert "field rate_hz = 'fast': Input should be a valid number (allowed: >= 1 and < 100)" in got
    assert "field flag = 1: Input should be a valid boolean (allowed: true or false)" in got
    assert "field inner.name = 3: Input should be a valid string (allowed: a string)" in got
    assert "field inner.gian = 2.0: unknown key; did you mean 'gain'? (allowed keys: gain, name)" in got
    assert ("field extra = 1: unknown key (allowed keys: rate_hz, count, flag, inner, table, items, pair, need)"
            in got)
    assert _problems({"need": "1"}) == ["field need = '1': Input should be a valid number (allowed: a finite number)"]
    assert _problems({"need": 1.0, "count": 1.5})[0].endswith("(allowed: >= 0)")
    long = _problems({"need": "x" * 100})[0]
    assert f"= '{'x' * 56}...: " in long  # a long value is cut at 60 characters


def test_top_level_and_file_errors_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"^s: 1 problem\(s\):\n  - expected a table/object at the top level, "
                                          r"found list$"):
        validate_config([1], _Doc, "s")
    cases = {"a.toml": ("x = [", "not valid TOML"), "b.json": ("{\n  1", "not valid JSON: .* at line 2, column 3"),
             "c.json": ("[1, 2]", "expected an object at the top level, found list")}
    for name, (text, words) in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(ConfigError, match=rf"(?s)^{tmp_path / name}: 1 problem.*{words}"):
            load_config(tmp_path / name, _Doc)
    with pytest.raises(ConfigError, match=r"(?s)nope.toml.*file not found"):
        load_config(tmp_path / "nope.toml", _Doc)
    (tmp_path / "bin.json").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ConfigError, match=r"(?s)bin.json.*cannot read"):
        load_config(tmp_path / "bin.json", _Doc)
    (tmp_path / "ok.TOML").write_text("need = 2.0\n[inner]\ngain = 0.5\n")
    doc = load_config(tmp_path / "ok.TOML", _Doc)  # the suffix in any case
    assert (doc.need, doc.inner.gain, doc.rate_hz) == (2.0, 0.5, 50.0)


def test_field_bounds_and_allowed_keys_resolve_nested_locations() -> None:
    from fmu_models.config import allowed_keys, field_bounds

    assert field_bounds(_Doc, ("rate_hz",)) == {"ge": 1.0, "lt": 100.0}
    assert field_bounds(_Doc, ("table", "k", "gain")) == {"gt": 0.0, "le": 5.0}
    assert field_bounds(_Doc, ("items", 3)) == {"ge": -1.0, "le": 1.0}
    assert field_bounds(_Doc, ("pair", "1")) == {"ge": 2.0} and field_bounds(_Doc, ("pair", 0)) == {}
    assert field_bounds(_Doc, ("nothing",)) == {} and field_bounds(_Doc, ("flag", "x")) == {}
    assert allowed_keys(_Doc, ("inner",)) == ["gain", "name"] and allowed_keys(_Doc, ("rate_hz",)) == []
    assert allowed_keys(_Doc, ("table", "any")) == ["gain", "name"] and allowed_keys(None, ()) == []


@dataclass(frozen=True)
class _Options:
    steps: int = bounded(10, 1, 100)
    gain: float = bounded(0.5, 0.0, 1.0, "s")
    limit: float | None = bounded(None, 0.0, 5.0, optional=True)
    plain: float = 3.0


def test_range_problems_of_bounded_options() -> None:
    assert range_problems(_Options()) == []
    assert range_problems(_Options(steps=1, gain=1.0, limit=5.0)) == []  # both ends are allowed
    assert range_problems(_Options(steps=0, gain=1.5, limit=-1.0, plain=1e9)) == [
        "steps = 0; allowed range [1, 100] (an integer)", "gain = 1.5; allowed range [0.0, 1.0] s",
        "limit = -1.0; allowed range [0.0, 5.0] or None"]
    assert range_problems(_Options(steps=2.0, gain=True)) == [  # type: ignore[arg-type]
        "steps = 2.0; allowed range [1, 100] (an integer)", "gain = True; allowed range [0.0, 1.0] s"]
    assert range_problems(_Options(steps=101, gain=float("nan"))) == [
        "steps = 101; allowed range [1, 100] (an integer)", "gain = nan; allowed range [0.0, 1.0] s"]
