"""ROS 1 wire format for types known only at run time.

A message is a ``dict`` of field name to value: numbers, ``str``, ``(secs, nsecs)`` for
time and duration, ``bytes`` for ``uint8``/``int8`` arrays, lists for other arrays, dicts for
nested messages. Codecs are compiled once per type into closures; decoding checks every
length against the bytes present, so a hostile frame raises instead of allocating.
An array's count is checked against the smallest size its elements can have (at least a
byte each, so an array of empty messages may not be longer than the bytes that follow it:
a count that costs no bytes on the wire would otherwise allocate without bound).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

from ..errors import OutOfRangeError, ProtocolError
from .ros1_types import BYTE_TYPES, PRIMITIVES, STRUCT_CODES, Field, TypeRegistry

Decoder = Callable[[memoryview, int], tuple[Any, int]]
Encoder = Callable[[Any, list[bytes]], None]

_U32 = struct.Struct("<I")
_TIME = {"time": struct.Struct("<II"), "duration": struct.Struct("<ii")}


def _need(buf: memoryview, off: int, n: int) -> None:
    if n < 0 or off + n > len(buf):
        raise ProtocolError(
            f"truncated message: need {n} bytes at offset {off}, have {len(buf) - off}"
        )


def _read_len(buf: memoryview, off: int) -> tuple[int, int]:
    _need(buf, off, 4)
    return _U32.unpack_from(buf, off)[0], off + 4


class Ros1Codec:
    """Serialises and deserialises dict messages of the types in a registry."""

    def __init__(self, registry: TypeRegistry) -> None:
        self.registry = registry
        self._decoders: dict[str, Decoder] = {}
        self._encoders: dict[str, Encoder] = {}

    def forget(self) -> None:
        """Recompile on next use (a definition changed)."""
        self._decoders = {}
        self._encoders = {}

    def decode(self, type_name: str, data: bytes | memoryview) -> dict[str, Any]:
        buf = memoryview(data)
        value, off = self._decoder(type_name)(buf, 0)
        if off != len(buf):
            raise ProtocolError(f"{type_name}: {len(buf) - off} bytes left over after the message")
        result: dict[str, Any] = value
        return result

    def encode(self, type_name: str, value: dict[str, Any]) -> bytes:
        """ROS 1 bytes of ``value``; OutOfRangeError for a number its field cannot hold
        (a negative ``time``, 300 in a ``uint8``), ProtocolError for other misfits."""
        out: list[bytes] = []
        try:
            self._encoder(type_name)(value, out)
        except (struct.error, OverflowError) as exc:
            text = str(exc)
            if "range" in text or "format requires" in text or "too large" in text:
                raise OutOfRangeError(f"{type_name}: {text}") from None
            raise ProtocolError(f"{type_name}: {text}") from None
        return b"".join(out)

    # --- decoding --------------------------------------------------------------------

    def _decoder(self, type_name: str) -> Decoder:
        found = self._decoders.get(type_name)
        if found is None:
            found = self._compile_decoder(type_name)
            self._decoders[type_name] = found
        return found

    def _compile_decoder(self, type_name: str) -> Decoder:
        spec = self.registry.get(type_name)
        parts = [(f.name, self._field_decoder(f)) for f in spec.fields]

        def decode(buf: memoryview, off: int) -> tuple[Any, int]:
            out: dict[str, Any] = {}
            for name, dec in parts:
                out[name], off = dec(buf, off)
            return out, off

        return decode

    def _field_decoder(self, f: Field) -> Decoder:
        elem = self._element_decoder(f.type)
        if f.array is None:
            return elem
        fixed = f.array
        if f.type in BYTE_TYPES:

            def dec_bytes(buf: memoryview, off: int) -> tuple[Any, int]:
                n = fixed
                if n < 0:
                    n, off = _read_len(buf, off)
                _need(buf, off, n)
                return bytes(buf[off : off + n]), off + n

            return dec_bytes
        if f.type in STRUCT_CODES:
            code = STRUCT_CODES[f.type]
            size = struct.calcsize(code)

            def dec_numbers(buf: memoryview, off: int) -> tuple[Any, int]:
                n = fixed
                if n < 0:
                    n, off = _read_len(buf, off)
                _need(buf, off, n * size)
                return list(struct.unpack_from(f"<{n}{code}", buf, off)), off + n * size

            return dec_numbers

        least = max(1, self._min_size(f.type))

        def dec_list(buf: memoryview, off: int) -> tuple[Any, int]:
            n = fixed
            if n < 0:
                n, off = _read_len(buf, off)
            _need(buf, off, n * least)  # bounds a bogus count before anything is allocated
            items = []
            for _ in range(n):
                item, off = elem(buf, off)
                items.append(item)
            return items, off

        return dec_list

    def _min_size(self, type_name: str) -> int:
        """Fewest bytes a value of ``type_name`` takes on the wire."""
        if type_name == "string":
            return 4
        if type_name in PRIMITIVES:
            return PRIMITIVES[type_name]
        total = 0
        for f in self.registry.get(type_name).fields:
            if f.array is None:
                total += self._min_size(f.type)
            elif f.array < 0:
                total += 4
            else:
                total += f.array * self._min_size(f.type)
        return total

    def _element_decoder(self, type_name: str) -> Decoder:
        if type_name == "string":

            def dec_str(buf: memoryview, off: int) -> tuple[Any, int]:
                n, off = _read_len(buf, off)
                _need(buf, off, n)
                try:
                    return str(buf[off : off + n], "utf-8"), off + n
                except UnicodeDecodeError as exc:
                    raise ProtocolError(f"string field is not UTF-8: {exc}") from None

            return dec_str
        if type_name in _TIME:
            st = _TIME[type_name]

            def dec_time(buf: memoryview, off: int) -> tuple[Any, int]:
                _need(buf, off, 8)
                return st.unpack_from(buf, off), off + 8

            return dec_time
        if type_name in STRUCT_CODES:
            st1 = struct.Struct("<" + STRUCT_CODES[type_name])
            size = st1.size

            def dec_num(buf: memoryview, off: int) -> tuple[Any, int]:
                _need(buf, off, size)
                return st1.unpack_from(buf, off)[0], off + size

            return dec_num
        # nested: resolved lazily so recursive compilation needs no ordering
        return lambda buf, off: self._decoder(type_name)(buf, off)

    # --- encoding --------------------------------------------------------------------

    def _encoder(self, type_name: str) -> Encoder:
        found = self._encoders.get(type_name)
        if found is None:
            found = self._compile_encoder(type_name)
            self._encoders[type_name] = found
        return found

    def _compile_encoder(self, type_name: str) -> Encoder:
        spec = self.registry.get(type_name)
        parts = [(f.name, self._field_encoder(f)) for f in spec.fields]

        def encode(value: Any, out: list[bytes]) -> None:
            for name, enc in parts:
                enc(value[name], out)

        return encode

    def _field_encoder(self, f: Field) -> Encoder:
        elem = self._element_encoder(f.type)
        if f.array is None:
            return elem
        fixed = f.array
        where = f"{f.name} ({f.spec_type()})"

        def check(n: int, out: list[bytes]) -> None:
            if fixed < 0:
                out.append(_U32.pack(n))
            elif n != fixed:
                raise ProtocolError(f"{where}: {n} elements for a fixed array of {fixed}")

        if f.type in BYTE_TYPES:

            def enc_bytes(value: Any, out: list[bytes]) -> None:
                data = value if isinstance(value, bytes) else _as_bytes(value, f.type)
                check(len(data), out)
                out.append(data)

            return enc_bytes
        if f.type in STRUCT_CODES:
            code = STRUCT_CODES[f.type]

            def enc_numbers(value: Any, out: list[bytes]) -> None:
                n = len(value)
                check(n, out)
                out.append(struct.pack(f"<{n}{code}", *value))

            return enc_numbers

        def enc_list(value: Any, out: list[bytes]) -> None:
            check(len(value), out)
            for item in value:
                elem(item, out)

        return enc_list

    def _element_encoder(self, type_name: str) -> Encoder:
        if type_name == "string":

            def enc_str(value: Any, out: list[bytes]) -> None:
                data = value.encode() if isinstance(value, str) else bytes(value)
                out.append(_U32.pack(len(data)))
                out.append(data)

            return enc_str
        if type_name in _TIME:
            st = _TIME[type_name]
            return lambda value, out: out.append(st.pack(*value))
        if type_name in STRUCT_CODES:
            st1 = struct.Struct("<" + STRUCT_CODES[type_name])
            return lambda value, out: out.append(st1.pack(value))
        return lambda value, out: self._encoder(type_name)(value, out)


def _as_bytes(value: Any, type_name: str) -> bytes:
    tobytes = getattr(value, "tobytes", None)
    if tobytes is not None and getattr(value, "itemsize", 1) == 1:
        data: bytes = tobytes()
        return data
    if isinstance(value, bytearray | memoryview):
        return bytes(value)
    code = "b" if type_name in ("int8", "byte") else "B"
    return struct.pack(f"<{len(value)}{code}", *value)
