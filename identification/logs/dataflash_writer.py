"""ArduPilot DataFlash binary (``.bin``) log writer, for synthetic test logs and converted flight data.

pymavlink only *reads* DataFlash logs (:class:`pymavlink.DFReader.DFReader_binary`); it has no writer, so this
module is hand-written against the layout that reader parses (and ArduPilot's AP_Logger writes):

* every message is ``0xA3 0x95 <type byte> <payload>``, little-endian, packed, no padding or checksum;
* type 128 is ``FMT`` (format ``"BBnNZ"``, columns ``Type,Length,Name,Format,Columns``): it declares the type id,
  the total length (3 header bytes + payload), the name (char[4]), the format string (char[16]) and the
  comma-separated column names (char[64]) of one message; the FMT of FMT itself is the first message of the file;
* the format characters are those of DFReader's ``FORMAT_TO_STRUCT`` (see :data:`FORMAT_CODES`); ``c C e E`` are
  integers holding value * 100 and ``L`` an int32 holding degrees * 1e7, which DFReader scales back.

``write`` takes scaled columns in natural units (degrees for ``L``, the column's unit for ``c C e E``) and
rounds them to the stored integers. Only the messages declared by :func:`DataFlashWriter.define` (or the
standard layouts below, defined on first use) are written; FMTU/UNIT/MULT unit metadata is not written, the
``units`` of a :class:`MessageLayout` document what ``write`` expects.
"""

from __future__ import annotations

import math
import numbers
import os
import struct
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO

import numpy as np

HEAD_BYTE_1 = 0xA3  #: first sync byte of every message
HEAD_BYTE_2 = 0x95  #: second sync byte of every message
HEADER_LEN = 3  #: sync bytes + type byte
FMT_TYPE_ID = 128  #: message type id of FMT
FIRST_TYPE_ID = 129  #: first type id handed out by :meth:`DataFlashWriter.define`
LAST_TYPE_ID = 255  #: the type id is one byte
NAME_MAX_LEN = 4  #: FMT.Name is char[4]
FORMAT_MAX_LEN = 16  #: FMT.Format is char[16]
COLUMNS_MAX_LEN = 64  #: FMT.Columns is char[64]
ARRAY_LEN = 32  #: format ``a`` is int16[32]
US_PER_S = 1_000_000


class DataFlashFormatError(ValueError):
    """A message definition or value that cannot be written; the message names the message, field and value."""


@dataclass(frozen=True)
class FormatCode:
    """How one DataFlash format character is stored: ``struct`` code, kind and the stored = value * ``factor``."""

    struct_code: str
    kind: str  # "int", "float", "str" or "array"
    factor: float | None = None  # scaled integers: stored = round(value * factor)


#: DataFlash format characters, as DFReader.FORMAT_TO_STRUCT unpacks them (``M`` is ArduPilot's uint8 flight mode;
#: pymavlink unpacks it as int8, so modes above 127 read back negative).
FORMAT_CODES: dict[str, FormatCode] = {
    "a": FormatCode(f"{2 * ARRAY_LEN}s", "array"),  # int16[32], packed by _array_bytes
    "b": FormatCode("b", "int"),
    "B": FormatCode("B", "int"),
    "g": FormatCode("e", "float"),  # IEEE half
    "h": FormatCode("h", "int"),
    "H": FormatCode("H", "int"),
    "i": FormatCode("i", "int"),
    "I": FormatCode("I", "int"),
    "f": FormatCode("f", "float"),
    "d": FormatCode("d", "float"),
    "n": FormatCode("4s", "str"),
    "N": FormatCode("16s", "str"),
    "Z": FormatCode("64s", "str"),
    "c": FormatCode("h", "int", 100.0),
    "C": FormatCode("H", "int", 100.0),
    "e": FormatCode("i", "int", 100.0),
    "E": FormatCode("I", "int", 100.0),
    "L": FormatCode("i", "int", 1.0e7),
    "M": FormatCode("B", "int"),
    "q": FormatCode("q", "int"),
    "Q": FormatCode("Q", "int"),
}


def _int_range(code: str) -> tuple[int, int]:
    bits = 8 * struct.calcsize(code)
    return (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if code.islower() else (0, (1 << bits) - 1)


@dataclass(frozen=True)
class MessageLayout:
    """One DataFlash message: ``name`` (<= 4 chars), ``fmt`` (one format character per column), ``columns``.

    ``columns`` may be given as ``"A,B,C"`` or a sequence; ``units`` (optional, one per column) documents the
    units :meth:`DataFlashWriter.write` expects. Construction validates everything FMT can hold and raises
    :class:`DataFlashFormatError` otherwise.
    """

    name: str
    fmt: str
    columns: tuple[str, ...]
    units: tuple[str, ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        cols, units = _names(self.columns), _names(self.units)
        object.__setattr__(self, "columns", cols)
        object.__setattr__(self, "units", units)
        where = f"message {self.name!r}"
        _check_ascii(where, "name", self.name, NAME_MAX_LEN)
        if not self.name:
            raise DataFlashFormatError(f"{where}: field 'name' is empty")
        _check_ascii(where, "format", self.fmt, FORMAT_MAX_LEN)
        for col, ch in zip(cols, self.fmt, strict=False):
            if ch not in FORMAT_CODES:
                raise DataFlashFormatError(
                    f"{where}: column {col!r} has unknown format character {ch!r} (format {self.fmt!r}; "
                    f"known: {''.join(FORMAT_CODES)})"
                )
        if len(cols) != len(self.fmt):
            raise DataFlashFormatError(
                f"{where}: field 'columns' has {len(cols)} names {','.join(cols)!r} but field 'format' "
                f"{self.fmt!r} has {len(self.fmt)} characters"
            )
        _check_ascii(where, "columns", ",".join(cols), COLUMNS_MAX_LEN)
        seen: set[str] = set()
        for col in cols:
            if not col.isidentifier():
                raise DataFlashFormatError(f"{where}: column name {col!r} is not an identifier")
            if col in seen:
                raise DataFlashFormatError(f"{where}: column name {col!r} appears twice")
            seen.add(col)
        if units and len(units) != len(cols):
            raise DataFlashFormatError(
                f"{where}: field 'units' has {len(units)} entries {units!r} for {len(cols)} columns"
            )

    @property
    def struct_format(self) -> str:
        """The little-endian ``struct`` format of the payload."""
        return "<" + "".join(FORMAT_CODES[c].struct_code for c in self.fmt)

    @property
    def length(self) -> int:
        """Total message length [bytes]: header + payload, as written in FMT.Length."""
        return HEADER_LEN + struct.calcsize(self.struct_format)


def _names(names: str | Sequence[str]) -> tuple[str, ...]:
    """``"A,B"`` or ``["A", "B"]`` -> ``("A", "B")``; ``""`` -> ``()``."""
    if isinstance(names, str):
        return tuple(names.split(",")) if names else ()
    return tuple(names)


def _layout(name: str, fmt: str, columns: str, units: str) -> MessageLayout:
    return MessageLayout(name, fmt, _names(columns), _names(units))


def _check_ascii(where: str, what: str, value: str, max_len: int) -> None:
    if not isinstance(value, str) or not value.isascii() or "\0" in value:
        raise DataFlashFormatError(f"{where}: field {what!r} must be an ASCII string without NUL, got {value!r}")
    if len(value) > max_len:
        raise DataFlashFormatError(
            f"{where}: field {what!r} value {value!r} is {len(value)} characters long, at most {max_len} fit"
        )


FMT = _layout("FMT", "BBnNZ", "Type,Length,Name,Format,Columns", "-,bytes,-,-,-")
#: TimeUS [us], Name, Value (parameter value as float32)
PARM = _layout("PARM", "QNf", "TimeUS,Name,Value", "us,-,-")
#: I is the IMU instance; gyro [rad/s], accelerometer [m/s^2], body FRD axes
IMU = _layout("IMU", "QBffffff", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ", "us,-,rad/s,rad/s,rad/s,m/s2,m/s2,m/s2")
#: desired and actual Euler angles [deg]
ATT = _layout("ATT", "Qffffff", "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw", "us,deg,deg,deg,deg,deg,deg")
#: servo/ESC outputs 1..14 [us PWM]
RCOU = _layout(
    "RCOU", "Q" + "H" * 14, "TimeUS," + ",".join(f"C{n}" for n in range(1, 15)), "us," + ",".join(["us"] * 14)
)
#: GMS GPS ms of week, GWk week, HDop [-], Lat/Lng [deg], Alt [m AMSL], Spd [m/s], GCrs [deg], VZ [m/s], Yaw [deg]
GPS = _layout(
    "GPS",
    "QBBIHBcLLeffffB",
    "TimeUS,I,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs,VZ,Yaw,U",
    "us,-,-,ms,week,-,-,deg,deg,m,m/s,deg,m/s,deg,-",
)
#: Alt [m above home], Press [Pa], Temp [degC]
BARO = _layout("BARO", "QBfff", "TimeUS,I,Alt,Press,Temp", "us,-,m,Pa,degC")
#: ArduCopter control tuning: altitudes [m] (BAlt stored in cm), DCRt/CRt climb rates [cm/s] as in ArduCopter 4.x
CTUN = _layout(
    "CTUN",
    "Qffffffefffhh",
    "TimeUS,ThI,ABst,ThO,ThH,DAlt,Alt,BAlt,DSAlt,SAlt,TAlt,DCRt,CRt",
    "us,-,-,-,-,m,m,m,m,m,m,cm/s,cm/s",
)
#: Airspeed [m/s], DiffPress [Pa], Temp [degC], RawPress [Pa], Offset [Pa], U use, H healthy, Hp health prob [%]
ARSP = _layout(
    "ARSP", "QBffcffBBb", "TimeUS,I,Airspeed,DiffPress,Temp,RawPress,Offset,U,H,Hp", "us,-,m/s,Pa,degC,Pa,Pa,-,-,%"
)
#: events: Id 10 armed, 11 disarmed, ...
EV = _layout("EV", "QB", "TimeUS,Id", "us,-")
#: battery monitor (ArduPilot 4.x): Volt/VoltR [V], Curr [A], CurrTot [Ah], EnrgTot [Wh], Temp [degC], Res [Ohm]
BAT = _layout(
    "BAT", "QBfffffcfBBB", "TimeUS,Inst,Volt,VoltR,Curr,CurrTot,EnrgTot,Temp,Res,RemPct,H,SH",
    "us,-,V,V,A,Ah,Wh,degC,Ohm,%,-,-",
)

#: Layouts ``write``/``write_log`` define on first use, by name.
STANDARD_LAYOUTS: dict[str, MessageLayout] = {
    m.name: m for m in (PARM, IMU, ATT, RCOU, GPS, BARO, CTUN, ARSP, EV, BAT)
}


@dataclass(frozen=True)
class _Defined:
    type_id: int
    layout: MessageLayout
    packer: struct.Struct
    index: dict[str, int]


class DataFlashWriter:
    """Writes a DataFlash ``.bin`` log; use as ``with DataFlashWriter(path) as w: ...``.

    The FMT of FMT is written on opening; :meth:`define` writes the FMT of a message, :meth:`write` one message.
    A message that fails validation raises :class:`DataFlashFormatError` and writes nothing.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self._file: BinaryIO | None = self.path.open("wb")
        self._defined: dict[str, _Defined] = {}
        self._next_type_id = FIRST_TYPE_ID
        self._fmt = _Defined(FMT_TYPE_ID, FMT, struct.Struct(FMT.struct_format), {})
        self._write_fmt(FMT_TYPE_ID, FMT)

    def __enter__(self) -> DataFlashWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        """Flush and close the file (idempotent)."""
        if self._file is not None:
            self._file.close()
            self._file = None

    @property
    def layouts(self) -> dict[str, MessageLayout]:
        """The messages defined so far, by name."""
        return {n: d.layout for n, d in self._defined.items()}

    def type_id(self, name: str) -> int:
        """The type id assigned to message ``name`` (129 up, in order of definition)."""
        return self._lookup(name).type_id

    def define(
        self, name: str, fmt: str, columns: str | Sequence[str], units: str | Sequence[str] = ()
    ) -> MessageLayout:
        """Declare message ``name`` with format ``fmt`` and ``columns`` (``"A,B"`` or a list) and write its FMT.

        Raises :class:`DataFlashFormatError` when the name is longer than 4 characters, the format longer than
        16, a format character unknown, the column count differs from the format length, a column name repeats,
        ``name`` is already defined differently or all 127 type ids are used.
        """
        return self.define_layout(MessageLayout(name, fmt, _names(columns), _names(units)))

    def define_layout(self, layout: MessageLayout) -> MessageLayout:
        """Write the FMT of ``layout``; defining the same layout twice is a no-op."""
        old = self._defined.get(layout.name)
        if old is not None:
            if old.layout != layout:
                raise DataFlashFormatError(
                    f"message {layout.name!r}: already defined as format {old.layout.fmt!r} columns "
                    f"{','.join(old.layout.columns)!r}, cannot redefine as {layout.fmt!r} {','.join(layout.columns)!r}"
                )
            return old.layout
        if self._next_type_id > LAST_TYPE_ID:
            raise DataFlashFormatError(
                f"message {layout.name!r}: no type id left, ids {FIRST_TYPE_ID}..{LAST_TYPE_ID} are all used"
            )
        type_id = self._next_type_id
        self._write_fmt(type_id, layout)
        self._next_type_id += 1
        self._defined[layout.name] = _Defined(
            type_id, layout, struct.Struct(layout.struct_format), {c: i for i, c in enumerate(layout.columns)}
        )
        return layout

    def write(self, name: str, **fields: Any) -> None:
        """Write one ``name`` message; ``fields`` by column name (``TimeUS`` [us] and the columns' units).

        Scaled columns are given in natural units: ``L`` in degrees, ``c C e E`` in the column's unit (stored
        as value * 100). Integer columns are rounded to the nearest integer; missing columns are written as 0
        (empty for strings). A standard layout (:data:`STANDARD_LAYOUTS`) is defined on first use. Unknown
        columns, non-finite or out-of-range integers and too long strings raise :class:`DataFlashFormatError`.
        """
        d = self._lookup(name)
        values: list[Any] = [None] * len(d.layout.columns)
        for key, value in fields.items():
            i = d.index.get(key)
            if i is None:
                raise DataFlashFormatError(
                    f"message {name!r}: field {key!r} (value {value!r}) is not a column; "
                    f"columns: {','.join(d.layout.columns)}"
                )
            values[i] = value
        self._emit(d, values)

    def param(self, time_us: int, name: str, value: float) -> None:
        """Write a PARM message: parameter ``name`` (<= 16 chars) = ``value`` (stored as float32) at ``time_us``."""
        self.write("PARM", TimeUS=time_us, Name=name, Value=value)

    # -- internals -------------------------------------------------------------------------------------------

    def _lookup(self, name: str) -> _Defined:
        d = self._defined.get(name)
        if d is None:
            if name not in STANDARD_LAYOUTS:
                raise DataFlashFormatError(
                    f"message {name!r}: not defined (call define() first); defined: {', '.join(self._defined)}; "
                    f"standard: {', '.join(STANDARD_LAYOUTS)}"
                )
            self.define_layout(STANDARD_LAYOUTS[name])
            d = self._defined[name]
        return d

    def _write_fmt(self, type_id: int, layout: MessageLayout) -> None:
        values = [type_id, layout.length, layout.name, layout.fmt, ",".join(layout.columns)]
        self._emit(self._fmt, values)

    def _emit(self, d: _Defined, values: Sequence[Any]) -> None:
        if self._file is None:
            raise ValueError(f"{self.path}: the DataFlash writer is closed")
        stored = [
            _stored_value(d.layout.name, col, ch, v)
            for col, ch, v in zip(d.layout.columns, d.layout.fmt, values, strict=True)
        ]
        try:
            payload = d.packer.pack(*stored)
        except (struct.error, OverflowError) as err:  # float32/half overflow
            bad = next(
                (
                    f"field {c!r} value {v!r}"
                    for c, ch, v in zip(d.layout.columns, d.layout.fmt, values, strict=True)
                    if not _packs(ch, v)
                ),
                "a field",
            )
            raise DataFlashFormatError(f"message {d.layout.name!r}: {bad} cannot be stored ({err})") from err
        self._file.write(bytes((HEAD_BYTE_1, HEAD_BYTE_2, d.type_id)) + payload)


def _packs(ch: str, value: Any) -> bool:
    try:
        struct.pack("<" + FORMAT_CODES[ch].struct_code, _stored_value("", "", ch, value))
    except (struct.error, OverflowError, DataFlashFormatError):
        return False
    return True


def _stored_value(msg: str, col: str, ch: str, value: Any) -> Any:
    """``value`` converted to what ``struct`` packs for format character ``ch`` (scaling, rounding, encoding)."""
    code = FORMAT_CODES[ch]
    where = f"message {msg!r}: field {col!r}"
    if code.kind == "str":
        if value is None:
            return b""
        raw = value.encode("utf-8") if isinstance(value, str) else value
        if not isinstance(raw, bytes | bytearray):
            raise DataFlashFormatError(f"{where} value {value!r} is not a string")
        width = struct.calcsize(code.struct_code)
        if len(raw) > width:
            raise DataFlashFormatError(f"{where} value {value!r} is {len(raw)} bytes long, at most {width} fit")
        return bytes(raw)
    if code.kind == "array":
        items = list(value) if value is not None else []
        if len(items) > ARRAY_LEN:
            raise DataFlashFormatError(f"{where} value {value!r} has {len(items)} items, at most {ARRAY_LEN} fit")
        return _array_bytes(where, value, items)
    if value is None:
        return 0 if code.kind == "int" else 0.0
    if not isinstance(value, numbers.Real | np.bool_):
        raise DataFlashFormatError(f"{where} value {value!r} is not a real number")
    if code.kind == "float":
        return float(value)
    x = float(value) * code.factor if code.factor is not None else value
    if isinstance(x, float | np.floating):
        if not math.isfinite(x):
            raise DataFlashFormatError(f"{where} value {value!r} is not finite; integer format {ch!r} needs one")
        x = round(x)
    x = int(x)
    lo, hi = _int_range(code.struct_code)
    if not lo <= x <= hi:
        scale = f" (x {code.factor:g} = {x})" if code.factor is not None else ""
        raise DataFlashFormatError(
            f"{where} value {value!r}{scale} is out of range for format {ch!r}: stored integer must be in {lo}..{hi}"
        )
    return x


def _array_bytes(where: str, value: Any, items: list[Any]) -> bytes:
    out = []
    for item in items:
        if isinstance(item, bool) or not isinstance(item, numbers.Integral) or not -32768 <= int(item) <= 32767:
            raise DataFlashFormatError(f"{where} value {value!r}: item {item!r} is not an int16")
        out.append(int(item))
    out += [0] * (ARRAY_LEN - len(out))
    return struct.pack(f"<{ARRAY_LEN}h", *out)


def define_standard(writer: DataFlashWriter, names: Iterable[str] | None = None) -> None:
    """Write the FMT of the standard layouts ``names`` (default: all of :data:`STANDARD_LAYOUTS`)."""
    for name in STANDARD_LAYOUTS if names is None else names:
        if name not in STANDARD_LAYOUTS:
            raise DataFlashFormatError(
                f"message {name!r}: not a standard layout; standard: {', '.join(STANDARD_LAYOUTS)}"
            )
        writer.define_layout(STANDARD_LAYOUTS[name])


Stream = tuple[Any, Mapping[str, Any]]


def write_log(
    path: str | os.PathLike[str],
    streams: Mapping[str, Stream],
    params: Mapping[str, float] | None = None,
    layouts: Iterable[MessageLayout] = (),
) -> Path:
    """Write a whole log: ``streams`` maps a message name to ``(t_s, {column: values})``.

    ``t_s`` are times [s] since boot (stored as ``TimeUS`` = round(t_s * 1e6) [us]); each column is an array of
    the same length as ``t_s`` or a scalar, in the units of :meth:`DataFlashWriter.write`. The FMTs come first,
    then the ``params`` as PARM messages at time 0, then all messages interleaved in time order (on equal times
    in the order of ``streams``, then of the samples). Messages not in :data:`STANDARD_LAYOUTS` need their layout
    in ``layouts``. Returns the path; on an error the partly written file is removed.
    """
    extra = {lay.name: lay for lay in layouts}
    prepared = [_prepare_stream(name, t_s, columns, extra) for name, (t_s, columns) in streams.items()]
    out = Path(path)
    try:
        with DataFlashWriter(out) as w:
            defined = [_define(w, p.layout) for p in prepared]
            if params:
                w.define_layout(PARM)
                for pname, value in params.items():
                    w.param(0, pname, value)
            if prepared:
                time_us = np.concatenate([p.time_us for p in prepared])
                stream_ix = np.concatenate([np.full(p.time_us.size, k) for k, p in enumerate(prepared)])
                row_ix = np.concatenate([np.arange(p.time_us.size) for p in prepared])
                order = np.lexsort((row_ix, stream_ix, time_us))
                for k, r, tu in zip(
                    stream_ix[order].tolist(), row_ix[order].tolist(), time_us[order].tolist(), strict=True
                ):
                    p, d = prepared[k], defined[k]
                    values: list[Any] = [None] * len(d.layout.columns)
                    values[d.index["TimeUS"]] = tu
                    for i, column_rows in zip(p.column_ix, p.rows, strict=True):
                        values[i] = column_rows[r]
                    w._emit(d, values)
    except BaseException:
        out.unlink(missing_ok=True)
        raise
    return out


def _define(writer: DataFlashWriter, layout: MessageLayout) -> _Defined:
    writer.define_layout(layout)
    return writer._lookup(layout.name)


@dataclass(frozen=True)
class _Prepared:
    layout: MessageLayout
    time_us: np.ndarray
    column_ix: list[int]
    rows: list[list[Any]]


def _prepare_stream(name: str, t_s: Any, columns: Mapping[str, Any], extra: Mapping[str, MessageLayout]) -> _Prepared:
    """Check one ``write_log`` stream against its layout before anything is written."""
    layout = extra.get(name) or STANDARD_LAYOUTS.get(name)
    if layout is None:
        raise DataFlashFormatError(
            f"message {name!r}: not a standard layout ({', '.join(STANDARD_LAYOUTS)}) and not in layouts"
        )
    if "TimeUS" not in layout.columns:
        raise DataFlashFormatError(f"message {name!r}: has no 'TimeUS' column to store t_s in")
    t = np.asarray(t_s, dtype=float).reshape(-1)
    bad = ~np.isfinite(t) | (t < 0.0)
    if bad.any():
        raise DataFlashFormatError(f"message {name!r}: field 't_s' value {t[bad][0]!r} is not a finite time >= 0 s")
    index = {c: i for i, c in enumerate(layout.columns)}
    column_ix, rows = [], []
    for col, vals in columns.items():
        if col == "TimeUS":
            raise DataFlashFormatError(f"message {name!r}: field 'TimeUS' is set from t_s, do not pass it as a column")
        if col not in index:
            raise DataFlashFormatError(
                f"message {name!r}: field {col!r} is not a column; columns: {','.join(layout.columns)}"
            )
        arr = np.asarray(vals)
        if arr.ndim == 0:
            arr = np.broadcast_to(arr, t.shape)
        if arr.shape != t.shape:
            raise DataFlashFormatError(
                f"message {name!r}: field {col!r} has {arr.size} values (shape {arr.shape}), t_s has {t.size}"
            )
        column_ix.append(index[col])
        rows.append(arr.tolist())
    return _Prepared(layout, np.round(t * US_PER_S).astype(np.int64), column_ix, rows)
