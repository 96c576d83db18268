"""Typed values as JSON, read back by their type: the codec of the analysis record and of the
analysis JSON (:mod:`bench.report.analysis_document`).

:func:`to_json_tree` turns a value into plain JSON data by its type hint, :func:`from_json_tree`
rebuilds the value from the same hint, so a reader gets the result classes back, not a tree of keys
to look up. The layout follows the type:

- a dataclass: an object, one member per field given to ``__init__``;
- ``bool``, ``int``, ``str``: themselves; ``float``: a number, or ``"nan"``, ``"inf"``, ``"-inf"``
  (JSON has no non-finite numbers); ``complex``: ``[real, imaginary]``; an enum: its value;
- ``numpy.ndarray``: ``{"dtype": "float64", "shape": [...], "data": [...]}``, the elements in C
  order as above (a complex array as ``"real"`` and ``"imag"`` lists);
- ``tuple[X, ...]``, ``list[X]`` and fixed tuples: a list of the items;
- ``dict[str, V]`` and ``Mapping[str, V]``: an object, its members in the mapping's order (read
  back from a list of ``[key, value]`` pairs too: the layout of every mapping before, which the
  analysis records of format 3 hold);
- ``dict[K, V]`` and ``Mapping[K, V]`` of other keys: a list of ``[key, value]`` pairs (keys are any
  of these types: floats and tuples are no JSON object keys), in the mapping's order;
- ``X | None``: X, or ``null``; ``float | numpy.ndarray``: as its value is;
- ``typing.Any``: JSON's own values (a scalar, a list, an object of string keys; numpy scalars and
  arrays as their Python values and lists, tuples as lists, a non-finite float as
  ``{"float": "nan"}``), read back as such.

Numbers are written with the shortest text that reads back to the same double, so a value read
back equals the one written to the last digit. Anything of another form than its type asks raises
:class:`TypedFormatError` naming the place (``shaker[0].amplitudes[1].frfs``): a record is read
whole or not at all.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import math
import sys
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

_SCALARS = (bool, int, float, complex, str)
_NON_FINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}


class TypedFormatError(ValueError):
    """Stored data that is not what its type asks; ``str`` names the place in the value."""


def to_json_tree(value: object, hint: object, where: str = "") -> Any:
    """``value`` as JSON data laid out by its type ``hint`` (the module's docstring). TypeError for a
    value or hint the codec does not know."""
    return _WRITERS[_kind(hint, where)](value, hint, where)


def from_json_tree(tree: Any, hint: object, where: str = "") -> Any:
    """The value :func:`to_json_tree` laid out as ``tree`` with type ``hint``."""
    return _READERS[_kind(hint, where)](tree, hint, where)


def _kind(hint: object, where: str) -> str:
    """Which layout a type has: the key of :data:`_WRITERS` and :data:`_READERS`."""
    origin = typing.get_origin(hint)
    kinds = (
        ("union", origin in (typing.Union, types.UnionType)),
        ("dataclass", dataclasses.is_dataclass(hint)),
        ("enum", isinstance(hint, type) and issubclass(hint, enum.Enum)),
        ("scalar", hint in _SCALARS),
        ("any", hint is Any),
        ("array", hint is np.ndarray),
        ("sequence", origin in (tuple, list)),
        ("mapping", origin in (dict, Mapping)),
    )
    for kind, matches in kinds:
        if matches:
            return kind
    raise TypeError(f"{where}: the typed codec does not know {hint}")


def _write_union(value: object, hint: object, where: str) -> Any:
    args = typing.get_args(hint)
    if value is None:
        if type(None) not in args:
            raise TypeError(f"{where}: None where {hint} is asked")
        return None
    return to_json_tree(value, _union_arm(args, value, where), where)


def _read_union(tree: Any, hint: object, where: str) -> Any:
    args = typing.get_args(hint)
    if tree is None:
        if type(None) in args:
            return None
        raise TypedFormatError(f"{where}: null where {hint} is asked")
    arms = [arm for arm in args if arm is not type(None)]
    if len(arms) > 1:  # float | ndarray: an array is stored as an object
        arms = [arm for arm in arms if (arm is np.ndarray) == isinstance(tree, dict)]
    if len(arms) != 1:
        raise TypedFormatError(f"{where}: stored as none of {args}")
    return from_json_tree(tree, arms[0], where)


def _write_dataclass(value: object, hint: object, where: str) -> Any:
    return {
        name: to_json_tree(getattr(value, name), field_hint, f"{where}.{name}")
        for name, field_hint in _init_fields(hint)  # type: ignore[arg-type]
    }


def _read_dataclass(tree: Any, hint: object, where: str) -> Any:
    assert isinstance(hint, type)
    fields = _init_fields(hint)
    if not isinstance(tree, dict) or set(tree) != {name for name, _ in fields}:
        got = sorted(tree) if isinstance(tree, dict) else type(tree).__name__
        raise TypedFormatError(f"{where}: not a {hint.__name__} (members {got})")
    values = {name: from_json_tree(tree[name], h, f"{where}.{name}") for name, h in fields}
    try:
        return hint(**values)
    except (TypeError, ValueError) as err:
        raise TypedFormatError(f"{where}: not a {hint.__name__}: {err}") from err


def _write_enum(value: object, hint: object, where: str) -> Any:
    return hint(value).value  # type: ignore[operator]


def _read_enum(tree: Any, hint: object, where: str) -> Any:
    try:
        return hint(tree)  # type: ignore[operator]
    except ValueError as err:
        raise TypedFormatError(f"{where}: {err}") from err


def _read_scalar(tree: Any, hint: object, where: str) -> Any:
    return _scalar(tree, hint, where)  # type: ignore[arg-type]


def _any_tree(value: object, hint: object = Any, where: str = "") -> Any:
    """A value of no declared type as JSON's own (the module's docstring)."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return {"float": _scalar_tree(value)}
    if isinstance(value, list | tuple):
        return [_any_tree(item, Any, f"{where}[{i}]") for i, item in enumerate(value)]
    if isinstance(value, Mapping):
        if not all(isinstance(key, str) for key in value):
            raise TypeError(f"{where}: a mapping of other keys than strings")
        return {key: _any_tree(item, Any, f"{where}[{key!r}]") for key, item in value.items()}
    if value is None or isinstance(value, bool | int | float | str):
        return value
    raise TypeError(f"{where}: {type(value).__name__} has no JSON form")


def _read_any(tree: Any, hint: object, where: str) -> Any:
    if isinstance(tree, list):
        return [_read_any(item, Any, f"{where}[{i}]") for i, item in enumerate(tree)]
    if isinstance(tree, dict):
        if set(tree) == {"float"}:
            return _scalar(tree["float"], float, where)
        return {key: _read_any(item, Any, f"{where}[{key!r}]") for key, item in tree.items()}
    return tree


def _write_sequence(value: object, hint: object, where: str) -> Any:
    items = list(value)  # type: ignore[call-overload]
    item_hints = _item_hints(hint, len(items), where)
    pairs = enumerate(zip(items, item_hints, strict=True))
    return [to_json_tree(item, h, f"{where}[{i}]") for i, (item, h) in pairs]


def _read_sequence(tree: Any, hint: object, where: str) -> Any:
    if not isinstance(tree, list):
        raise TypedFormatError(f"{where}: {type(tree).__name__} where a sequence is asked")
    item_hints = _item_hints(hint, len(tree), where)
    pairs = enumerate(zip(tree, item_hints, strict=True))
    items = [from_json_tree(item, h, f"{where}[{i}]") for i, (item, h) in pairs]
    return tuple(items) if typing.get_origin(hint) is tuple else items


def _write_mapping(value: object, hint: object, where: str) -> Any:
    key_hint, value_hint = typing.get_args(hint)
    if key_hint is str:
        return _write_object(value, value_hint, where)  # type: ignore[arg-type]
    pairs = []
    for key, item in value.items():  # type: ignore[attr-defined]
        place = f"{where}[{key!r}]"
        pairs.append([to_json_tree(key, key_hint, place), to_json_tree(item, value_hint, place)])
    return pairs


def _read_mapping(tree: Any, hint: object, where: str) -> Any:
    key_hint, value_hint = typing.get_args(hint)
    if key_hint is str and isinstance(tree, dict):
        return {key: from_json_tree(item, value_hint, f"{where}[{key!r}]") for key, item in tree.items()}
    if not isinstance(tree, list) or not all(isinstance(p, list) and len(p) == 2 for p in tree):
        layouts = "neither an object nor a list" if key_hint is str else "not a list"
        raise TypedFormatError(f"{where}: {layouts} of [key, value] pairs")
    out = {}
    for i, (key, item) in enumerate(tree):
        place = f"{where}[{i}]"
        out[from_json_tree(key, key_hint, place)] = from_json_tree(item, value_hint, place)
    return out


def _write_object(value: Mapping[Any, Any], value_hint: object, where: str) -> dict[str, Any]:
    """A mapping of string keys as a JSON object (another key would become text unseen)."""
    tree = {}
    for key, item in value.items():
        if not isinstance(key, str):
            raise TypeError(f"{where}: key {key!r} of a mapping of strings")
        tree[str(key)] = to_json_tree(item, value_hint, f"{where}[{key!r}]")
    return tree


@functools.cache
def _init_fields(cls: type) -> tuple[tuple[str, object], ...]:
    """The fields ``cls.__init__`` takes, with their resolved type hints."""
    hints = typing.get_type_hints(cls, vars(sys.modules[cls.__module__]))
    return tuple((f.name, hints[f.name]) for f in dataclasses.fields(cls) if f.init)


def _union_arm(args: tuple[object, ...], value: object, where: str) -> object:
    """The arm of a union that ``value`` is an instance of."""
    for arm in args:
        if arm is type(None):
            continue
        number = isinstance(value, int | float | np.floating | np.integer) and not isinstance(value, bool)
        if arm is float and number:
            return arm
        base = typing.get_origin(arm) or arm
        if isinstance(base, type) and isinstance(value, base):
            return arm
    raise TypeError(f"{where}: {type(value).__name__} is none of {args}")


def _item_hints(hint: object, n: int, where: str) -> tuple[object, ...]:
    """The type of each of ``n`` items of a tuple or list type."""
    args = typing.get_args(hint)
    if typing.get_origin(hint) is list or (len(args) == 2 and args[1] is Ellipsis):
        return (args[0],) * n
    if len(args) != n:
        raise TypedFormatError(f"{where}: {n} items where {hint} has {len(args)}")
    return args


def _scalar_tree(value: object, hint: object = Any, where: str = "") -> Any:
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else "inf" if value > 0 else "-inf"
    if isinstance(value, complex):
        return [_scalar_tree(value.real), _scalar_tree(value.imag)]
    if not isinstance(value, bool | int | float | str):
        raise TypeError(f"{where}: {type(value).__name__} is no scalar")
    return value


def _scalar(tree: Any, kind: type, where: str) -> Any:
    """``tree`` as ``kind``, refused when it is of another kind (a string for a number)."""
    if kind is complex:
        if not isinstance(tree, list) or len(tree) != 2:
            raise TypedFormatError(f"{where}: {tree!r} is not a [real, imaginary] pair")
        return complex(_scalar(tree[0], float, where), _scalar(tree[1], float, where))
    if kind is float and isinstance(tree, str) and tree in _NON_FINITE:
        return _NON_FINITE[tree]
    ok = {
        bool: lambda v: isinstance(v, bool),
        int: lambda v: isinstance(v, int) and not isinstance(v, bool),
        float: lambda v: isinstance(v, int | float) and not isinstance(v, bool),
        str: lambda v: isinstance(v, str),
    }[kind](tree)
    if not ok:
        raise TypedFormatError(f"{where}: {tree!r} is not a {kind.__name__}")
    return kind(tree)


def _flat(array: np.ndarray) -> list[Any]:
    """An array's elements as JSON numbers (non-finite floats as their names)."""
    items = array.ravel().tolist()
    if array.dtype.kind == "f" and not np.isfinite(array).all():
        for i in np.flatnonzero(~np.isfinite(array)):
            items[i] = _scalar_tree(float(array.flat[i]))
    return items


def _array_tree(value: object, hint: object = np.ndarray, where: str = "") -> dict[str, Any]:
    array = np.asarray(value)
    if array.dtype.kind not in "biufc":
        raise TypeError(f"{where}: an array of {array.dtype} is not stored")
    tree: dict[str, Any] = {"dtype": array.dtype.name, "shape": list(array.shape)}
    if array.dtype.kind == "c":
        tree.update(real=_flat(array.real), imag=_flat(array.imag))
    else:
        tree["data"] = _flat(array)
    return tree


def _array(tree: Any, hint: object, where: str) -> np.ndarray:
    complex_parts = isinstance(tree, dict) and "real" in tree
    members = {"dtype", "shape", "real", "imag"} if complex_parts else {"dtype", "shape", "data"}
    if not isinstance(tree, dict) or set(tree) != members:
        raise TypedFormatError(f"{where}: not an array")
    try:
        dtype = np.dtype(tree["dtype"])
        shape = tuple(int(n) for n in tree["shape"])
        if dtype.kind not in "biufc":
            raise TypeError(f"dtype {dtype}")
        if dtype.kind == "c":
            real, imag = (np.array(tree[part], dtype=np.float64) for part in ("real", "imag"))
            array = (real + 1j * imag).astype(dtype)
        else:  # numpy reads the names of non-finite floats as such
            array = np.array(tree["data"], dtype=dtype)
        return array.reshape(shape)
    except (TypeError, ValueError) as err:
        raise TypedFormatError(f"{where}: not an array: {err}") from err


#: How each kind of type (:func:`_kind`) is laid out, and read back.
_WRITERS: dict[str, Callable[[Any, object, str], Any]] = {
    "union": _write_union,
    "dataclass": _write_dataclass,
    "enum": _write_enum,
    "scalar": _scalar_tree,
    "any": _any_tree,
    "array": _array_tree,
    "sequence": _write_sequence,
    "mapping": _write_mapping,
}
_READERS: dict[str, Callable[[Any, object, str], Any]] = {
    "union": _read_union,
    "dataclass": _read_dataclass,
    "enum": _read_enum,
    "scalar": _read_scalar,
    "any": _read_any,
    "array": _array,
    "sequence": _read_sequence,
    "mapping": _read_mapping,
}
