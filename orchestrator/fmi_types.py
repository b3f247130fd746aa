"""The FMI type system as the master sees it: what each declared type is (family, width,
signedness), which connections are lossless, how a value from a system file is checked against
a type without silent conversion, and the Parquet type it is recorded with.

A variable's ``fmi_type`` is the name its model description declares (FMI 2: Real, Integer,
Enumeration, Boolean, String; FMI 3: Float32, Float64, Int8 ... UInt64, Boolean, String, Binary,
Enumeration). Python components declare Real, Integer, Boolean or String, read as FMI 2's.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from orchestrator.errors import SystemError_


@dataclass(frozen=True)
class TypeInfo:
    family: str   # "float", "int", "enum", "bool", "string", "binary"
    bits: int     # storage width (0 for string and binary)
    signed: bool
    family_name: str  # the coarse name VarInfo.type carries: Real, Integer, Boolean, String, Binary


TYPES: dict[str, TypeInfo] = {
    "Real": TypeInfo("float", 64, True, "Real"),
    "Float64": TypeInfo("float", 64, True, "Real"),
    "Float32": TypeInfo("float", 32, True, "Real"),
    "Integer": TypeInfo("int", 32, True, "Integer"),
    "Int8": TypeInfo("int", 8, True, "Integer"),
    "Int16": TypeInfo("int", 16, True, "Integer"),
    "Int32": TypeInfo("int", 32, True, "Integer"),
    "Int64": TypeInfo("int", 64, True, "Integer"),
    "UInt8": TypeInfo("int", 8, False, "Integer"),
    "UInt16": TypeInfo("int", 16, False, "Integer"),
    "UInt32": TypeInfo("int", 32, False, "Integer"),
    "UInt64": TypeInfo("int", 64, False, "Integer"),
    "Boolean": TypeInfo("bool", 1, False, "Boolean"),
    "String": TypeInfo("string", 0, False, "String"),
    "Binary": TypeInfo("binary", 0, False, "Binary"),
}
# an enumeration is an Int32 in FMI 2 and an Int64 in FMI 3
ENUM2 = TypeInfo("enum", 32, True, "Integer")
ENUM3 = TypeInfo("enum", 64, True, "Integer")


def info(fmi_type: str, fmi3: bool = False) -> TypeInfo:
    if fmi_type == "Enumeration":
        return ENUM3 if fmi3 else ENUM2
    try:
        return TYPES[fmi_type]
    except KeyError:
        raise SystemError_(f"type {fmi_type!r} is not an FMI 2 or FMI 3 variable type") from None


def int_range(t: TypeInfo) -> tuple[int, int]:
    if t.signed:
        return -(1 << (t.bits - 1)), (1 << (t.bits - 1)) - 1
    return 0, (1 << t.bits) - 1


def exact_in_float64(t: TypeInfo) -> bool:
    """Can every value of the type travel in a float64 exchange slot without loss? (The native
    loop and the recording's numeric block hold float64; 64-bit integers, strings and binaries
    travel as Python objects.)"""
    return t.family in ("float", "bool") or (t.family in ("int", "enum") and t.bits <= 32)


def connectable(src: TypeInfo, dst: TypeInfo) -> bool:
    """Lossless only: the same type, a wider float, a wider integer of a signedness that holds
    every source value, an integer of at most 32 bits into Float64, an integer into an
    enumeration and back (they are the same integers in FMI)."""
    if src == dst:
        return True
    ints = ("int", "enum")
    if src.family == "float" and dst.family == "float":
        return dst.bits >= src.bits
    if src.family in ints and dst.family in ints:
        # Integer <-> Enumeration: the same integers, so only the width matters
        if src.signed == dst.signed:
            return dst.bits >= src.bits
        return (not src.signed) and dst.signed and dst.bits > src.bits
    if src.family in ints and dst.family == "float":
        # a float64 holds every integer up to 2^53, a float32 up to 2^24
        return src.bits <= (32 if dst.bits == 64 else 16)
    return False


def check_value(t: TypeInfo, value, where: str):
    """*value* (from a system file or a component) as a value of type *t*, refused when it would
    have to be rounded, truncated or reinterpreted."""
    def refuse(expected: str):
        raise SystemError_(f"{where} = {value!r}: expected {expected}")

    if t.family == "float":
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            refuse("a number")
        return float(value)
    if t.family in ("int", "enum"):
        if isinstance(value, bool):
            refuse("an integer, not a Boolean")
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if not isinstance(value, numbers.Integral):
            refuse("an integer (a value with a fraction is not rounded)")
        lo, hi = int_range(t)
        if not lo <= int(value) <= hi:
            refuse(f"an integer in [{lo}, {hi}]")
        return int(value)
    if t.family == "bool":
        if not isinstance(value, bool):
            refuse("true or false")
        return value
    if t.family == "string":
        if not isinstance(value, str):
            refuse("a string")
        return value
    if isinstance(value, (bytes, bytearray)):
        return bytes(value)
    if isinstance(value, str):
        try:
            return bytes.fromhex(value)
        except ValueError:
            refuse("bytes, or a string of hexadecimal digits")
    refuse("bytes, or a string of hexadecimal digits")


def from_slot(t: TypeInfo, x):
    """A value taken from an exchange slot (float64 or object) as the target's type."""
    if t.family == "float":
        return float(x)
    if t.family in ("int", "enum"):
        if isinstance(x, float):
            if not math.isfinite(x):
                raise ValueError(f"{x} is not an integer")
            return int(x)
        return int(x)
    if t.family == "bool":
        return bool(x)
    return x


ARROW_TYPES = {"float": {64: "float64", 32: "float32"}, "bool": {1: "bool_"},
               "string": {0: "string"}, "binary": {0: "binary"}}


def arrow_type(t: TypeInfo):
    """The Parquet (arrow) type a variable of type *t* is recorded with."""
    import pyarrow as pa

    if t.family in ("int", "enum"):
        return getattr(pa, f"{'' if t.signed else 'u'}int{t.bits}")()
    return getattr(pa, ARROW_TYPES[t.family][t.bits])()
