"""The SHA-256 of a value by what it holds: what an analysis read (its record's ``inputs_sha256``)
and what a figure shows (a kept figure's ``shows_sha256``).

The value is walked field by field: a dataclass by its class name and each field's name and value,
an array by its type, shape and bytes, a mapping and a sequence by their length and items in
order, a number by its value as a double whatever its Python or numpy type (``1``, ``1.0``,
``numpy.float64(1.0)`` and an int enum of 1 digest alike; every NaN alike), text by its text (a
string enum too), another enum by its class and member, booleans and None by their text. Equal
values give equal digests in any process, whichever route they took there (a pickle, a record
read back). A value of any other type raises TypeError: its text (an object's address) would give
another digest every time.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
from collections.abc import Mapping
from typing import Any

import numpy as np


def value_sha256(value: object, *prefix: str) -> str:
    """The SHA-256 (hex) of ``prefix`` (text taken as it is) and then ``value``."""
    digest = hashlib.sha256()
    for text in prefix:
        digest.update(text.encode())
    _update(digest, value)
    return digest.hexdigest()


def _update(digest: Any, value: object) -> None:
    if isinstance(value, np.generic):
        value = value.item()
    if (text := _scalar_text(value)) is not None:
        digest.update(text.encode())
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        digest.update(type(value).__name__.encode())
        for field in dataclasses.fields(value):
            digest.update(field.name.encode())
            _update(digest, getattr(value, field.name))
    elif isinstance(value, np.ndarray):
        array = _canonical_nan(np.ascontiguousarray(value))
        digest.update(f"{array.dtype.str}{array.shape}".encode())
        digest.update(array.tobytes())
    elif isinstance(value, Mapping):
        digest.update(f"{{{len(value)}".encode())
        for key, item in value.items():
            _update(digest, key)
            _update(digest, item)
    elif isinstance(value, list | tuple):
        digest.update(f"[{len(value)}".encode())
        for item in value:
            _update(digest, item)
    else:
        raise TypeError(f"{type(value).__name__} has no digest by value")


def _scalar_text(value: object) -> str | None:
    """A scalar's text for the digest (None: not a scalar). A number as the double it is (an int
    enum too; an integer beyond a double's range as its digits), a string as itself (a string enum
    too), another enum by its class and member."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        try:
            return repr(float(value))
        except OverflowError:
            return repr(int(value))
    if isinstance(value, str):
        return repr(str.__str__(value))
    if isinstance(value, enum.Enum):
        return f"{type(value).__name__}.{value.name}"
    if value is None or isinstance(value, bool | complex):
        return repr(value)
    return None


def _canonical_nan(array: np.ndarray) -> np.ndarray:
    """``array`` with every NaN as numpy's own (a NaN's sign and payload bits differ with how it
    was made, and a record read back holds numpy's)."""
    if array.dtype.kind not in "fc" or not np.isnan(array).any():
        return array
    if array.dtype.kind == "c":
        return _canonical_nan(array.real) + 1j * _canonical_nan(array.imag)
    return np.where(np.isnan(array), np.array(np.nan, dtype=array.dtype), array)

