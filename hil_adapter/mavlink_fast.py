"""MAVLink 2 framing of the messages exchanged on every lockstep step, from pymavlink's own layouts.

pymavlink builds a message object, a header object and several byte arrays per message: about 7 us to pack
one and 10 us to parse one on a bench PC, tripled when the loop interleaves them with the FMU step. At
1-5 kHz lockstep that was most of the adapter's own cost per step, so the per-step messages are framed
here: the struct layout, field order, message id and CRC extra all come from pymavlink's generated classes
(nothing is declared twice), the checksum is pymavlink's ``x25crc``, and the tests check every byte against
pymavlink. Anything else (signed links, other messages, split or garbled frames) goes through pymavlink.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

MAGIC_V2 = 0xFD
#: MAVLink 2 header after the magic byte: len, incompat flags, compat flags, seq, sysid, compid, msgid (24 bit)
HEADER_V2 = struct.Struct("<BBBBBBBHB")
HEADER_LEN = HEADER_V2.size
#: the header as we send it, from the length on (incompat and compat flags 0: unsigned)
_HEADER_OUT = struct.Struct("<BxxBBBHB")
CRC = struct.Struct("<H")


#: fastcrc's CRC-16/MCRF4XX when pymavlink found it (what pymavlink's own ``x25crc`` calls), else None
_MCRF4XX = getattr(mavlink2, "mcrf4xx", None)


def _crc16(data: bytes) -> int:
    """MAVLink's X.25 (CRC-16/MCRF4XX) checksum, as pymavlink computes it (without its wrapper object)."""
    if _MCRF4XX is not None:
        return int(_MCRF4XX(data, 0xFFFF))
    return int(mavlink2.x25crc(data).crc)


def _crc16_pair(body: bytes, extra: bytes) -> int:
    """``_crc16(body + extra)`` without building the concatenation (the CRC register chains: no final XOR)."""
    if _MCRF4XX is not None:
        return int(_MCRF4XX(extra, _MCRF4XX(body, 0xFFFF)))
    return int(mavlink2.x25crc(body + extra).crc)


@dataclass(frozen=True)
class _Layout:
    """Wire layout of one message class: per wire field the declared argument index and array length."""

    msg_id: int
    crc_extra: bytes
    payload: struct.Struct
    wire: tuple[tuple[int, int], ...]
    defaults: tuple[Any, ...]
    #: wire order is the declared order and no field is an array: the arguments pack as they are
    flat: bool

    @classmethod
    def of(cls, msg_class: type) -> _Layout:
        names = list(msg_class.fieldnames)
        wire = tuple((names.index(n), length) for n, length in
                     zip(msg_class.ordered_fieldnames, msg_class.array_lengths, strict=True))
        flat = all(index == k and not length for k, (index, length) in enumerate(wire))
        # MAVLink 2 extension fields (declared after the base ones) default to zero, as in pymavlink
        return cls(msg_class.id, bytes((msg_class.crc_extra,)), msg_class.unpacker, wire,
                   tuple(0 for _ in names), flat)


class FastMavlink:
    """Packs messages and parses HIL_ACTUATOR_CONTROLS for a pymavlink ``MAVLink`` object it shares (same
    sequence number, system and component ids, same parser buffer)."""

    def __init__(self, mav: mavlink2.MAVLink) -> None:
        self.mav = mav
        self._layouts: dict[type, _Layout] = {}
        self._actuator = _Layout.of(mavlink2.MAVLink_hil_actuator_controls_message)

    def pack(self, msg_class: type, *args: Any) -> bytes:
        """One framed message; ``args`` in the order of ``msg_class``'s constructor (as pymavlink's
        ``*_encode``). Advances the sequence number like ``MAVLink.send``."""
        mav = self.mav
        lay = self._layouts.get(msg_class)
        if lay is None:
            lay = self._layouts[msg_class] = _Layout.of(msg_class)
        if mav.signing.sign_outgoing:  # rare on a simulator link: pymavlink signs
            buf = msg_class(*args).pack(mav)
        else:
            if len(args) < len(lay.defaults):
                args = args + lay.defaults[len(args):]
            if lay.flat:
                payload = lay.payload.pack(*args)
            else:
                values: list[Any] = []
                for index, length in lay.wire:
                    if length:
                        values.extend(args[index])
                    else:
                        values.append(args[index])
                payload = lay.payload.pack(*values)
            payload = payload.rstrip(b"\0") or b"\0"  # MAVLink 2 trims trailing zero bytes, keeps one
            body = _HEADER_OUT.pack(len(payload), mav.seq, mav.srcSystem, mav.srcComponent, lay.msg_id & 0xFFFF,
                                    lay.msg_id >> 16) + payload
            buf = b"\xfd" + body + CRC.pack(_crc16(body + lay.crc_extra))
        mav.seq = (mav.seq + 1) % 256
        return buf

    def pack_wire(self, msg_class: type, *values: Any) -> bytes:
        """``pack`` for values already flat and in wire order (arrays expanded, every field given): the
        per-step messages whose layout the caller knows (``HilMessages``); the tests check the bytes against
        pymavlink."""
        mav = self.mav
        lay = self._layouts.get(msg_class)
        if lay is None:
            lay = self._layouts[msg_class] = _Layout.of(msg_class)
        if mav.signing.sign_outgoing:
            return self.pack(msg_class, *_unflatten(lay, values))
        payload = lay.payload.pack(*values).rstrip(b"\0") or b"\0"
        seq = mav.seq
        body = _HEADER_OUT.pack(len(payload), seq, mav.srcSystem, mav.srcComponent, lay.msg_id & 0xFFFF,
                                lay.msg_id >> 16) + payload
        mav.seq = (seq + 1) % 256
        crc = (_MCRF4XX(lay.crc_extra, _MCRF4XX(body, 0xFFFF)) if _MCRF4XX is not None
               else _crc16_pair(body, lay.crc_extra))
        return b"".join((b"\xfd", body, CRC.pack(crc)))

    def actuator_controls(self, data: bytes) -> tuple[Sequence[float], int, int, bytes] | None:
        """``(controls[16], mode, flags, rest)`` when ``data`` starts with a whole, unsigned, valid
        HIL_ACTUATOR_CONTROLS frame and pymavlink holds no partial frame; else None (pymavlink parses)."""
        lay = self._actuator
        if (len(data) < HEADER_LEN + 2 or data[0] != MAGIC_V2 or data[2] != 0 or self.mav.buf_len() != 0
                or data[7] | data[8] << 8 | data[9] << 16 != lay.msg_id):
            return None
        plen = data[1]
        end = HEADER_LEN + plen + 2
        if plen > lay.payload.size or len(data) < end:
            return None
        if CRC.unpack_from(data, end - 2)[0] != _crc16_pair(data[1:HEADER_LEN + plen], lay.crc_extra):
            return None  # pymavlink counts it as bad data
        if plen == lay.payload.size:
            fields = lay.payload.unpack_from(data, HEADER_LEN)
        else:  # MAVLink 2 trimmed trailing zero bytes off the payload
            fields = lay.payload.unpack(data[HEADER_LEN:HEADER_LEN + plen] + bytes(lay.payload.size - plen))
        # wire order: time_usec, flags, controls[16], mode
        return fields[2:18], fields[18], fields[1], data[end:]


def _unflatten(lay: _Layout, values: Sequence[Any]) -> list[Any]:
    """Constructor arguments from flat wire-order values (the signed path goes through pymavlink)."""
    args: list[Any] = list(lay.defaults)
    pos = 0
    for index, length in lay.wire:
        if length:
            args[index] = list(values[pos:pos + length])
            pos += length
        else:
            args[index] = values[pos]
            pos += 1
    return args


__all__ = ["FastMavlink"]
