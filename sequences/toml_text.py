"""Reading and writing the flat TOML the sequence, configuration, answers and mapping files use:
:func:`load_toml` is the one way they are read (tomllib, with nesting too deep refused), and
:func:`toml_error_where` words its errors for a person."""

from __future__ import annotations

import json
import re
import tomllib
from collections.abc import Mapping
from typing import Any

#: The deepest nesting of arrays and tables a file may use, the file itself counted as a table (the
#: formats use a few: a grid's list of frequencies in a step of the steps array is 4). Deeper
#: nesting is refused as the file's error: tomllib itself fails on a few hundred levels with a
#: RecursionError, and so would any walk of the parsed data.
MAX_NESTING = 32
#: How :func:`load_toml` begins the message of a file nested too deep.
NESTED_TOO_DEEP = "nested too deep"


def load_toml(text: str) -> dict[str, Any]:
    """``tomllib.loads(text)``; arrays or tables nested more than :data:`MAX_NESTING` levels deep
    raise :class:`tomllib.TOMLDecodeError` saying so (whether tomllib ran out of stack on them or not),
    so that every reader reports it as the file's error and every walk of the data is shallow."""
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise tomllib.TOMLDecodeError(_too_deep()) from None
    if _depth(data) > MAX_NESTING:
        raise tomllib.TOMLDecodeError(_too_deep())
    return data


def _too_deep() -> str:
    return (
        f"{NESTED_TOO_DEEP}: arrays or tables nested more than {MAX_NESTING} levels deep (the files"
        " of this software nest a few levels at most)"
    )


def _depth(data: object) -> int:
    """How deep lists and tables nest in ``data`` (a table of scalars: 1), without recursion."""
    deepest, stack = 0, [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, dict):
            children = value.values()
        elif isinstance(value, list):
            children = value
        else:
            continue
        deepest = max(deepest, depth)
        if depth <= MAX_NESTING:  # deeper is refused anyway: no need to look further
            stack.extend((child, depth + 1) for child in children)
    return deepest


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


_AT_LINE = re.compile(r"\s*\(at line (\d+), column (\d+)\)")
_DUPLICATE = ("Cannot overwrite", "Cannot declare", "Duplicate")


def toml_error_where(text: str, message: str) -> tuple[str, str]:
    """The key a tomllib error of ``text`` points at and the error worded for a person: ``(key,
    "line N: duplicate key: ...")`` or ``(key, "line N: not valid TOML: ...")``. The key is dotted
    and prefixed by its table (``steps[2].freq_hz``: an array of tables counts from 0, as in
    Python), "" where no key can be told (the line holds none, or the message names no line)."""
    at = _AT_LINE.search(message)
    reason = _AT_LINE.sub("", message)
    if reason.startswith(NESTED_TOO_DEEP):
        return "", reason
    if at is None:
        return "", f"not valid TOML: {reason}"
    line = int(at[1])
    if reason.startswith(_DUPLICATE):
        reason = f"duplicate key: it is already defined above in the same table ({reason})"
    else:
        reason = f"not valid TOML: {reason}"
    return _key_at(text.splitlines(), line), f"line {line}: {reason}"


def _key_at(lines: list[str], line: int) -> str:
    """The dotted key defined on ``line`` (1-based), prefixed by the table it is in; an array of
    tables is indexed (``steps[2]``, ``runs[1].points[0]``)."""
    table, counts = "", {}
    for text in lines[: line - 1]:
        stripped = text.split("#", 1)[0].strip()
        if stripped.startswith("[["):
            name = stripped.strip("[]").strip()
            # a nested array ([[runs.points]]) counts afresh under each entry of its parent
            counts = {k: v for k, v in counts.items() if not k.startswith(f"{name}.")}
            counts[name] = counts.get(name, -1) + 1
            parts = name.split(".")
            table = ".".join(
                f"{part}[{counts['.'.join(parts[: i + 1])]}]" if ".".join(parts[: i + 1]) in counts else part
                for i, part in enumerate(parts)
            )
        elif stripped.startswith("["):
            table = stripped.strip("[]").strip()
    current = lines[line - 1].strip() if 0 < line <= len(lines) else ""
    if current.startswith("["):
        return current.strip("[]").strip()
    name = current.split("=", 1)[0].strip() if "=" in current else ""
    return ".".join(part for part in (table, name) if part)
