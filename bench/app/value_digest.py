"""The SHA-256 of a value by what it holds: what an analysis read (its record's ``inputs_sha256``)
and what a figure shows (a kept figure's ``shows_sha256``).

The value is walked field by field: a dataclass by its class name and each field's name and value,
an array by its type, shape and bytes, a mapping and a sequence by their length and items in
order, an enum by its class and member, a number by its value as a double whatever its Python or
numpy type (``1``, ``1.0`` and ``numpy.float64(1.0)`` digest alike), text, booleans and None by
their text. Equal values give equal digests in any process, whichever route they took there (a
pickle, a record read back). A value of any other type raises TypeError: its text (an object's
address) would give another digest every time.
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
    if isinstance(value, enum.Enum):
        digest.update(f"{type(value).__name__}.{value.name}".encode())
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        digest.update(type(value).__name__.encode())
        for field in dataclasses.fields(value):
            digest.update(field.name.encode())
            _update(digest, getattr(value, field.name))
    elif isinstance(value, np.ndarray):
        array = np.ascontiguousarray(value)
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
    elif isinstance(value, int | float) and not isinstance(value, bool):
        digest.update(repr(float(value)).encode())
    elif value is None or isinstance(value, bool | str | complex):
        digest.update(repr(value).encode())
    else:
        raise TypeError(f"{type(value).__name__} has no digest by value")
