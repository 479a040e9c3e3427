"""One config mechanism for every TOML/JSON file the project reads: typed pydantic v2 schemas.

Why pydantic v2 (and not msgspec): its errors carry the location, the offending input and the violated
constraint (``ge``, ``le``, ``gt``, ``lt``, literal choices) of *every* problem at once, which is what a
one-line message per problem naming file, field, value and allowed range needs; it has a strict mode that
rejects booleans and strings where numbers belong, and ``allow_inf_nan=False``; it is the most widely kept
validation library in the Python ecosystem. msgspec is faster, but stops at the first error.

Use::

    class MyConfig(Schema):
        rate_hz: PositiveFiniteFloat = 50.0
        mass_kg: float = Field(1.0, gt=0, le=50)

    cfg = load_config("bench.toml", MyConfig)      # ConfigError listing every problem, never a traceback
    cfg = validate_config(data_dict, MyConfig, source="bench.toml [hil]")
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import numbers
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, TypeVar, get_args, get_origin

from pydantic import BaseModel, ConfigDict, Field
from pydantic import ValidationError as PydanticValidationError
from pydantic.fields import FieldInfo

__all__ = [
    "ConfigError",
    "FiniteFloat",
    "NonNegativeFiniteFloat",
    "PositiveFiniteFloat",
    "Schema",
    "allowed_keys",
    "bounded",
    "field_bounds",
    "format_problems",
    "load_config",
    "range_problems",
    "read_config_file",
    "validate_config",
]

S = TypeVar("S", bound="Schema")

#: a float that is finite (NaN and inf rejected by the schema's ``allow_inf_nan=False``)
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
PositiveFiniteFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegativeFiniteFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]


class ConfigError(ValueError):
    """A config or parameter file is invalid; ``problems`` holds one line per problem.

    Named apart from FMPy's ``ValidationError`` (modelDescription findings) and pydantic's.
    """

    def __init__(self, source: str, problems: list[str]) -> None:
        self.source = source
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"{source}: {len(self.problems)} problem(s):\n{lines}")


class Schema(BaseModel):
    """Base of every config schema: unknown keys rejected, no bool/str coercion to numbers, no NaN/inf."""

    model_config = ConfigDict(
        extra="forbid", strict=True, allow_inf_nan=False, frozen=True, validate_default=True,
        populate_by_name=True,
    )


_BOUND_WORDS = {"ge": ">=", "gt": ">", "le": "<=", "lt": "<"}


def _unwrap(tp: Any, meta: list[Any]) -> Any:
    """``Annotated[T, ...]`` -> ``T``, its constraint objects appended to ``meta``."""
    while get_origin(tp) is Annotated:
        base, *extra = get_args(tp)
        for e in extra:
            meta.extend(e.metadata if isinstance(e, FieldInfo) else [e])
        tp = base
    return tp


def _resolve(schema: type[BaseModel] | None, loc: tuple[Any, ...]) -> tuple[Any, list[Any]] | None:
    """The type declared at ``loc`` of ``schema`` (through nested schemas, dicts, lists and tuples) and its
    constraint objects; ``None`` where the location cannot be resolved."""
    tp: Any = schema
    meta: list[Any] = []
    for part in loc:
        if isinstance(tp, type) and issubclass(tp, BaseModel):
            info = tp.model_fields.get(str(part))
            if info is None:
                return None
            meta = list(info.metadata)
            tp = _unwrap(info.annotation, meta)
            continue
        origin, args = get_origin(tp), get_args(tp)
        meta = []
        if origin is dict and len(args) == 2:
            tp = args[1]
        elif origin in (list, tuple) and args:
            idx = int(part) if isinstance(part, int) or str(part).isdigit() else 0
            tp = args[0] if args[-1] is Ellipsis else args[min(idx, len(args) - 1)]
        else:
            return None
        tp = _unwrap(tp, meta)
    return tp, meta


def field_bounds(schema: type[BaseModel] | None, loc: tuple[Any, ...]) -> dict[str, Any]:
    """The numeric bounds (``ge``/``gt``/``le``/``lt``) declared for the field at ``loc`` of ``schema``, so a
    message gives the whole allowed range and not only the violated side; ``{}`` where unknown."""
    found = _resolve(schema, loc)
    if found is None:
        return {}
    return {k: getattr(m, k) for m in found[1] for k in ("gt", "ge", "lt", "le") if getattr(m, k, None) is not None}


def allowed_keys(schema: type[BaseModel] | None, loc: tuple[Any, ...]) -> list[str]:
    """The keys the table at ``loc`` of ``schema`` accepts (``[]`` where it is not a schema)."""
    found = _resolve(schema, loc)
    tp = found[0] if found else None
    return list(tp.model_fields) if isinstance(tp, type) and issubclass(tp, BaseModel) else []


def _num(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _allowed(err: Mapping[str, Any], bounds: Mapping[str, Any]) -> str:
    ctx = err.get("ctx") or {}
    both = {**{k: ctx[k] for k in ("gt", "ge", "lt", "le") if k in ctx}, **bounds}
    words = " and ".join(f"{_BOUND_WORDS[k]} {_num(both[k])}" for k in ("gt", "ge", "lt", "le") if k in both)
    value = err.get("input")
    if isinstance(value, float) and not math.isfinite(value):
        return "allowed: a finite number" + (f" {words}" if words else "")
    if words:
        return "allowed: " + words
    if "expected" in ctx:
        return f"allowed: {ctx['expected']}"
    kind = str(err.get("type", ""))
    if kind.startswith(("float", "int")) or kind == "finite_number":
        return "allowed: a finite number"
    if kind.startswith("bool"):
        return "allowed: true or false"
    if kind.startswith("string"):
        return "allowed: a string"
    if kind == "extra_forbidden":
        return "unknown key"
    return ""


def format_problems(err: PydanticValidationError, schema: type[BaseModel] | None = None) -> list[str]:
    """One line per problem: ``field a.b.0 = <value>: <message> (<allowed>)``; with ``schema``, the allowed
    range names both bounds of a bounded number."""
    lines = []
    for e in err.errors(include_url=False):
        loc = ".".join(str(p) for p in e.get("loc", ())) or "(top level)"
        value = e.get("input")
        shown = repr(value)
        if len(shown) > 60:
            shown = shown[:57] + "..."
        allowed = _allowed(e, field_bounds(schema, tuple(e.get("loc", ()))))
        msg = e.get("msg", "invalid")
        if isinstance(value, float) and not math.isfinite(value):
            msg = "not finite"
        tail = f" ({allowed})" if allowed and allowed != "unknown key" else ""
        if e.get("type") == "missing":
            lines.append(f"field {loc}: missing (required)")
        elif e.get("type") == "extra_forbidden":
            keys = allowed_keys(schema, tuple(e.get("loc", ()))[:-1])
            close = difflib.get_close_matches(str(e["loc"][-1]), keys, n=1) if keys else []
            hint = (f"; did you mean '{close[0]}'?" if close else "") + (
                f" (allowed keys: {', '.join(keys)})" if keys else "")
            lines.append(f"field {loc} = {shown}: unknown key{hint}")
        else:
            lines.append(f"field {loc} = {shown}: {msg}{tail}")
    return lines


def validate_config(data: Any, schema: type[S], source: str) -> S:
    """Validate a decoded mapping against ``schema``; raise :class:`ConfigError` listing every problem."""
    if not isinstance(data, Mapping):
        raise ConfigError(source, [f"expected a table/object at the top level, found {type(data).__name__}"])
    try:
        return schema.model_validate(dict(data))
    except PydanticValidationError as err:
        raise ConfigError(source, format_problems(err, schema)) from None


def read_config_file(path: str | Path) -> dict[str, Any]:
    """Read a TOML (``.toml``) or JSON (anything else) file into a dict; errors name the file."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(str(p), ["file not found"]) from None
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(str(p), [f"cannot read: {err}"]) from None
    return parse_config_text(text, str(p), toml=p.suffix.lower() == ".toml")


def parse_config_text(text: str, source: str, toml: bool = False) -> dict[str, Any]:
    """The dict of a TOML or JSON text (a file's, or an FMU member's); :class:`ConfigError` naming ``source``."""
    try:
        data = tomllib.loads(text) if toml else json.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(source, [f"not valid TOML: {err}"]) from None
    except json.JSONDecodeError as err:
        raise ConfigError(source, [f"not valid JSON: {err.msg} at line {err.lineno}, column {err.colno}"]) from None
    if not isinstance(data, dict):
        raise ConfigError(source, [f"expected an object at the top level, found {type(data).__name__}"])
    return data


def load_config(path: str | Path, schema: type[S]) -> S:
    """Read and validate a config file; :class:`ConfigError` lists every problem with file and field."""
    return validate_config(read_config_file(path), schema, str(path))


# ------------------------------------------------------------------ options of library functions
def bounded(default: Any, lo: float, hi: float, unit: str = "", optional: bool = False) -> Any:
    """A field of a frozen options dataclass (what a library workflow takes) whose value must be a finite number
    (an integer where the field is annotated ``int``; never a boolean) in ``[lo, hi]``, or None when
    ``optional``. ``default`` may be ``dataclasses.MISSING`` (a required field). :func:`range_problems` checks
    every such field: the range is declared once, beside the field."""
    meta = {"bounds": (lo, hi), "unit": unit, "optional": optional}
    return dataclasses.field(metadata=meta) if default is dataclasses.MISSING else dataclasses.field(
        default=default, metadata=meta)


def range_problems(options: Any) -> list[str]:
    """One line per :func:`bounded` field of the dataclass ``options`` whose value is out of its declared kind
    or range: ``name = value; allowed range [lo, hi] unit``."""
    out = []
    for f in dataclasses.fields(options):
        spec = f.metadata.get("bounds")
        value = getattr(options, f.name)
        if spec is None or (value is None and f.metadata["optional"]):
            continue
        integer = f.type is int or str(f.type).split("|")[0].strip() == "int"  # annotation, or its text
        kind = numbers.Integral if integer else numbers.Real
        if isinstance(value, bool) or not isinstance(value, kind) or not (spec[0] <= value <= spec[1]):
            lo, hi = (int(b) for b in spec) if integer else (float(b) for b in spec)
            unit = f" {f.metadata['unit']}" if f.metadata["unit"] else ""
            what = " (an integer)" if integer else ""
            also = " or None" if f.metadata["optional"] else ""
            out.append(f"{f.name} = {value!r}; allowed range [{lo!r}, {hi!r}]{unit}{what}{also}")
    return out
