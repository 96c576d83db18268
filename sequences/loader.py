"""Sequence files: TOML in, a validated :class:`Sequence` out (format in ``docs/sequences.md``).

A file is read whole and every problem is collected before anything is refused: the structure
(tables, unknown and missing keys, step types) here, the values against the bench's limits in
:mod:`sequences.validation`, the same checks a sequence built in Python goes through. Duplicate
keys and TOML syntax errors stop the reading at once (tomllib refuses the whole file); their error
still names the line and, where it can be told, the key.
"""

from __future__ import annotations

import dataclasses
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path

from sequences.channels import ChannelSet
from sequences.errors import Problem, SequenceError
from sequences.limits import BenchLimits
from sequences.metadata import check_metadata
from sequences.steps import STEP_TYPES, AdaptiveDwell, DwellGrid, FreeRun, Sequence, Step, step_fields
from sequences.toml_text import load_toml, toml_error_where, toml_table
from sequences.validation import check_channels, check_sequence_header, check_steps

_TOP_KEYS = ("sequence", "steps", "metadata")
_HEADER_KEYS = ("name", "description")
#: Set by a grid's crossover on the dwells it expands to, never written in a file.
_DERIVED_KEYS = frozenset({"requested_amplitude_mm", "amplitude_limited_by"})
_STEP_INDEX = re.compile(r"^steps\[(\d+)\]")


def load_sequence(path: str | Path, limits: BenchLimits, channels: ChannelSet | None = None) -> Sequence:
    """Read, check and build the sequence in ``path``; :class:`SequenceError` lists every problem.
    Given the bench's recorded ``channels``, the channels the steps name or need are checked too."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SequenceError(str(path), "", f"cannot read the sequence file: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise SequenceError(str(path), "", f"not UTF-8 text: {exc.reason} at byte {exc.start}") from exc
    return parse_sequence(text, str(path), limits, channels)


def parse_sequence(
    text: str, source: str, limits: BenchLimits, channels: ChannelSet | None = None
) -> Sequence:
    """Check and build a sequence from TOML ``text``; ``source`` names it in errors."""
    try:
        data = load_toml(text)
    except tomllib.TOMLDecodeError as exc:
        raise _syntax_error(text, source, str(exc)) from None
    if not data:
        raise SequenceError(source, "", "empty file: a sequence needs a [sequence] table and [[steps]]")
    problems = [
        Problem(source, key, f"unknown key; allowed: {', '.join(_TOP_KEYS)}")
        for key in data
        if key not in _TOP_KEYS
    ]
    header = data.get("sequence")
    name, description = "", ""
    if isinstance(header, dict):
        problems += [
            Problem(source, f"sequence.{key}", f"unknown key; allowed: {', '.join(_HEADER_KEYS)}")
            for key in header
            if key not in _HEADER_KEYS
        ]
        name, description = header.get("name", ""), header.get("description", "")
        problems += check_sequence_header(name, description, source)
    elif header is not None or not problems:
        # without a [sequence] table, its name and description are not checked one by one; a
        # misspelt one ([sequenc]) is named by its unknown key already: nothing more to say
        problems.append(Problem(source, "sequence", "missing [sequence] table with name and description"))
    metadata, metadata_problems = check_metadata(data.get("metadata", {}))
    problems += [Problem(source, key, message) for key, message in metadata_problems]
    raw_steps = data.get("steps")
    steps: list[tuple[int, Step]] = []
    if not isinstance(raw_steps, list) or not raw_steps:
        problems.append(Problem(source, "steps", "a sequence needs at least one [[steps]] table"))
    else:
        for index, raw in enumerate(raw_steps):
            step = _build_step(index, raw, source, problems)
            if step is not None:
                steps.append((index, step))
        problems += check_steps(steps, limits, source)
        if channels is not None:
            problems += check_channels(steps, channels, source)
    if problems:
        raise SequenceError.of(sorted(problems, key=_file_order))
    return Sequence(name, description, tuple(step for _, step in steps), source, metadata)


def _file_order(problem: Problem) -> int:
    """Header problems first, then by step index (stable: each step's problems keep their order)."""
    match = _STEP_INDEX.match(problem.key)
    return int(match[1]) if match else -1


def _file_keys(cls: type) -> tuple[dict[str, bool], type]:
    """The keys a step type takes in a file (name -> required) and the dataclass they fill."""
    target = DwellGrid if cls is FreeRun else cls
    keys = {
        f.name: f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        for f in dataclasses.fields(target)
        if f.name not in _DERIVED_KEYS
    }
    return keys, target


def _build_step(index: int, raw: object, source: str, problems: list[Problem]) -> Step | None:
    """The step of one ``[[steps]]`` table, or None with its structural problems added."""
    key = f"steps[{index}]"
    if not isinstance(raw, dict):
        problems.append(Problem(source, key, f"must be a table, got {raw!r}"))
        return None
    kind = raw.get("type")
    if kind is None:
        problems.append(
            Problem(source, f"{key}.type", f"missing: a step needs type, one of {list(STEP_TYPES)}")
        )
        return None
    if not isinstance(kind, str) or kind not in STEP_TYPES:
        problems.append(
            Problem(source, f"{key}.type", f"unknown step type {kind!r}; use one of {list(STEP_TYPES)}")
        )
        return None
    keys, target = _file_keys(STEP_TYPES[kind])
    values = {name: tuple(v) if isinstance(v, list) else v for name, v in raw.items() if name in keys}
    for name in raw:
        if name != "type" and name not in keys:
            problems.append(
                Problem(source, f"{key}.{name}", f"unknown key for a {kind} step; allowed: {', '.join(keys)}")
            )
    missing = [name for name, required in keys.items() if required and name not in raw]
    for name in missing:
        problems.append(Problem(source, f"{key}.{name}", f"missing: a {kind} step needs {name}"))
    if "adaptive" in values:
        values["adaptive"] = _build_adaptive(f"{key}.adaptive", kind, values["adaptive"], source, problems)
        if values["adaptive"] is None:
            return None
    if missing:
        return None
    built = target(**values)
    return FreeRun(built) if STEP_TYPES[kind] is FreeRun else built


def step_from_fields(values: Mapping[str, object], source: str = "<record>") -> Step:
    """The step a run recorded (:func:`~sequences.steps.step_fields`, as a campaign file's
    ``step`` attribute holds it) built again; :class:`SequenceError` naming ``source`` when the
    fields are no step of this vocabulary. Its structure is checked, not its values against a
    bench's limits."""
    problems: list[Problem] = []
    recorded = {key: value for key, value in values.items() if key not in _DERIVED_KEYS}
    step = _build_step(0, recorded, source, problems)
    if problems or step is None:
        raise SequenceError.of(problems or [Problem(source, "steps[0]", "not a step")])
    return step


def _build_adaptive(
    key: str, kind: str, raw: object, source: str, problems: list[Problem]
) -> AdaptiveDwell | None:
    """The ``adaptive`` table of a dwell grid, or None with its structural problems added."""
    if kind != DwellGrid.kind:
        problems.append(Problem(source, key, f"a {kind} step has no adaptive table; only a dwell_grid has"))
        return None
    if not isinstance(raw, dict):
        problems.append(Problem(source, key, f"must be a table, got {raw!r}"))
        return None
    allowed = [f.name for f in dataclasses.fields(AdaptiveDwell)]
    unknown = [name for name in raw if name not in allowed]
    for name in unknown:
        problems.append(Problem(source, f"{key}.{name}", f"unknown key; allowed: {', '.join(allowed)}"))
    return None if unknown else AdaptiveDwell(**raw)


def _syntax_error(text: str, source: str, message: str) -> SequenceError:
    """A tomllib error as a :class:`SequenceError` naming the line and, where it can, the key."""
    key, reason = toml_error_where(text, message)
    return SequenceError(source, key, reason)


def dump_sequence(sequence: Sequence) -> str:
    """The sequence as a sequence file that :func:`parse_sequence` reads back to an equal sequence
    (for recording a scripted sequence with its run). A dwell's ``requested_amplitude_mm`` and
    ``amplitude_limited_by`` belong to the grid that expanded it and are not written."""
    lines = toml_table("[sequence]", {"name": sequence.name, "description": sequence.description})
    if sequence.metadata:
        lines += ["", *toml_table("[metadata]", sequence.metadata)]
    for step in sequence.steps:
        values = {k: v for k, v in step_fields(step).items() if k not in _DERIVED_KEYS}
        lines += ["", *toml_table("[[steps]]", values)]
    return "\n".join(lines) + "\n"
