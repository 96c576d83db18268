"""Analysis results as HDF5: a nested mapping becomes nested groups, arrays become datasets,
scalars and strings become attributes, anything else becomes JSON text.

The mapping is the one convention between the analysis and the file: the writer does not know the
analysis's result classes. Dataclass instances are taken field by field (so a result object can be
passed as it is). What neither HDF5 nor a plain value can hold (None, lists of strings or of
mappings) is written as a JSON attribute and listed in the group's ``json_keys`` attribute, so the
reader turns it back into the same value.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from bench.store.schema import GZIP_LEVEL, StoreError, from_json, to_json

JSON_KEYS = "json_keys"
_SCALARS = (bool, int, float, complex, str, np.bool_, np.number)
_COMPRESS_FROM = 1024  # arrays of at least this many elements are stored compressed


def as_mapping(value: object) -> Mapping[str, Any] | None:
    """``value`` as a mapping when it is one (or a dataclass instance), else None."""
    if isinstance(value, Mapping):
        return value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: getattr(value, f.name) for f in dataclasses.fields(value)}
    return None


def write_tree(group: h5py.Group, tree: Mapping[str, Any], *, path: str | Path) -> None:
    """Write ``tree`` under ``group`` (which must be empty); errors name the key's place."""
    json_keys = []
    for key, item in tree.items():
        where = f"{group.name}/{key}"
        if not isinstance(key, str) or not key or "/" in key or key in (".", JSON_KEYS):
            raise StoreError(path, where, f"key {key!r} cannot name an HDF5 object")
        value = item.value if isinstance(item, enum.Enum) else item
        mapping = as_mapping(value)
        if mapping is not None:
            write_tree(group.create_group(key), mapping, path=path)
        elif isinstance(value, _SCALARS):
            group.attrs[key] = value
        elif (array := _numeric_array(value)) is not None:
            compress = {"compression": "gzip", "compression_opts": GZIP_LEVEL, "shuffle": True}
            group.create_dataset(key, data=array, **(compress if array.size >= _COMPRESS_FROM else {}))
        else:
            group.attrs[key] = to_json(value, path=path, where=where)
            json_keys.append(key)
    if json_keys:
        group.attrs[JSON_KEYS] = json_keys


def _numeric_array(value: object) -> np.ndarray | None:
    """``value`` as a numeric (bool, integer, float or complex) array of at least one dimension."""
    if not isinstance(value, np.ndarray | list | tuple):
        return None
    try:
        array = np.asarray(value)
    except ValueError:  # ragged
        return None
    if array.ndim == 0 or array.dtype.kind not in "biufc":
        return None
    return array


def read_tree(group: h5py.Group, *, path: str | Path) -> dict[str, Any]:
    """The mapping :func:`write_tree` wrote: arrays as numpy arrays, scalars as Python values."""
    json_keys = {str(k) for k in group.attrs.get(JSON_KEYS, ())}
    out: dict[str, Any] = {}
    for key, value in group.attrs.items():
        if key == JSON_KEYS:
            continue
        if key in json_keys:
            out[key] = from_json(value, path=path, where=f"{group.name}@{key}")
        elif isinstance(value, np.generic):
            out[key] = value.item()
        else:
            out[key] = value
    for key, item in group.items():
        out[key] = read_tree(item, path=path) if isinstance(item, h5py.Group) else item[()]
    return out
