"""Writing the flat TOML the sequence and configuration files use (tomllib only reads)."""

from __future__ import annotations

import json
from collections.abc import Mapping


def toml_value(value: object) -> str:
    """One value as TOML: booleans, integers, floats (nan and inf too), strings and nested lists."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)  # Python writes floats, nan and inf as TOML does
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # JSON string escapes are TOML's
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write {value!r} as TOML")


def toml_table(header: str, values: Mapping[str, object]) -> list[str]:
    """The lines of one table (``header`` like ``[sequence]`` or ``[[steps]]``); None values are left out."""
    return [header, *(f"{key} = {toml_value(v)}" for key, v in values.items() if v is not None)]
