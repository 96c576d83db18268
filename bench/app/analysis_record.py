"""The post-run analysis kept as a record: each run's analysis stored beside it, read back typed.

After each run the analysis process makes the run's record (:func:`record_text`): what the analysis
gave (:class:`~bench.analysis.campaign.RunAnalysis`: its lines, scalars, flags and what it could not
give), what it established for the campaign (its changes to the
:class:`~bench.analysis.campaign.CampaignKnowledge`: the fits with their covariances, the FRFs with
their uncertainties, the valid bands with what ended them, the identification and the compensator
``wfsbench compensate`` uses), its place among the campaign's analyses, the software version that
made it and the SHA-256 of the inputs it read (:func:`inputs_sha256`). The recorder stores it as the
run's ``analysis`` (docs/hdf5.md, *The analysis record*): JSON laid out by the result types
(:mod:`bench.store.typed`), versioned by :data:`RECORD_FORMAT`.

:func:`stored_analysis` rebuilds the campaign's knowledge from the records, in the order the
analyses were made, so that ``analyze``, ``report``, ``export``, ``compensate`` and ``index`` read
what the analysis found instead of fitting again; it says why when it cannot (a run without a record,
a record of another format), and the reader then refits and says so.
"""

from __future__ import annotations

import dataclasses
import json
import typing
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from bench.analysis.campaign import CampaignKnowledge, RunAnalysis
from bench.app.run_analysis import RunAnalyser, RunInputs
from bench.app.value_digest import value_sha256
from bench.app.version import software_version
from bench.store import RunView
from bench.store.typed import TypedFormatError, from_json_tree, to_json_tree

#: The record's layout version: raised whenever a reader of the previous one would misread a record
#: (a result type's field renamed, retyped or given another meaning). A record of another format is
#: not read: its campaign is analysed again. 2: a shaker amplitude's band conditions; 3: a run's flags, typed.
#: 4: a mapping of string keys is a JSON object, no longer a list of [key, value] pairs.
RECORD_FORMAT = 4
#: The formats this version reads: 3 holds the same data as 4, its mappings as pairs (which the
#: codec reads too).
READ_FORMATS = (3, RECORD_FORMAT)
#: What an analysis changed in the campaign's knowledge, by field: ("set", value) for a field given
#: a new value, ("extend", items) for items appended to a list, ("update", items) for a dict's new or
#: replaced entries.
KnowledgeChanges = dict[str, tuple[str, Any]]
CHANGE_KINDS = ("set", "extend", "update")
#: Knowledge fields a record leaves out: the raw records the analysis took in, which the runs hold.
UNRECORDED_FIELDS = frozenset({"shaker_free_run", "post_free_run"})
_FIELD_HINTS = typing.get_type_hints(CampaignKnowledge)


@dataclass(frozen=True)
class AnalysisRecord:
    """One run's analysis as stored: ``outcome``, ``changes`` (knowledge field -> (kind, value)),
    ``order`` (0 for the campaign's first analysis), ``software_version`` and ``inputs_sha256``."""

    outcome: RunAnalysis
    changes: KnowledgeChanges
    order: int
    software_version: str
    inputs_sha256: str


def record_text(record: AnalysisRecord) -> str:
    """``record`` as the JSON text the run's ``analysis`` holds."""
    changes = [
        [name, kind, to_json_tree(value, _FIELD_HINTS[name], name)]
        for name, (kind, value) in record.changes.items()
        if name not in UNRECORDED_FIELDS
    ]
    tree = {
        "format": RECORD_FORMAT,
        "software_version": record.software_version,
        "inputs_sha256": record.inputs_sha256,
        "order": record.order,
        "outcome": to_json_tree(record.outcome, RunAnalysis, "outcome"),
        "changes": changes,
    }
    return json.dumps(tree, separators=(",", ":"), allow_nan=False)


def parse_record(text: str) -> AnalysisRecord:
    """The record :func:`record_text` wrote, or one of an earlier format this version reads
    (:data:`READ_FORMATS`); :class:`TypedFormatError` when ``text`` is none of these (the message
    says what is wrong)."""
    try:
        tree = json.loads(text)
    except json.JSONDecodeError as err:
        raise TypedFormatError(f"not JSON: {err}") from err
    if not isinstance(tree, dict):
        raise TypedFormatError("not a JSON object")
    if tree.get("format") not in READ_FORMATS:
        read = " and ".join(str(n) for n in READ_FORMATS)
        raise TypedFormatError(f"record format {tree.get('format')!r}, this version reads {read}")
    members = {"format", "software_version", "inputs_sha256", "order", "outcome", "changes"}
    if set(tree) != members:
        raise TypedFormatError(f"members {sorted(tree)}, not {sorted(members)}")
    changes = {}
    for entry in tree["changes"] if isinstance(tree["changes"], list) else [None]:
        known = isinstance(entry, list) and len(entry) == 3 and entry[0] in _FIELD_HINTS
        if not (known and entry[1] in CHANGE_KINDS):
            raise TypedFormatError(f"changes: {str(entry)[:80]} is no (field, kind, value) of the knowledge")
        name, kind, value = entry
        if name in UNRECORDED_FIELDS:
            raise TypedFormatError(f"changes: {name} is not recorded")
        changes[name] = (kind, from_json_tree(value, _FIELD_HINTS[name], name))
    order = tree["order"]
    if not isinstance(order, int) or isinstance(order, bool) or order < 0:
        raise TypedFormatError(f"order: {order!r} is no place")
    return AnalysisRecord(
        outcome=from_json_tree(tree["outcome"], RunAnalysis, "outcome"),
        changes=changes,
        order=order,
        software_version=from_json_tree(tree["software_version"], str, "software_version"),
        inputs_sha256=from_json_tree(tree["inputs_sha256"], str, "inputs_sha256"),
    )


def analyse_and_record(
    analyser: RunAnalyser, run: RunInputs, *, flag_defects: bool = False
) -> tuple[RunAnalysis, KnowledgeChanges, str]:
    """Analyse ``run`` with ``analyser``: its analysis, what it changed in the analyser's knowledge
    and its record's text. ``flag_defects``: an exception the analyser does not flag itself (a
    defect) is returned as a flagged analysis too, as the analysis process must answer every run, and
    a result the record cannot hold leaves the record empty (not stored: readers fit the run again)."""
    before = knowledge_snapshot(analyser.knowledge)
    try:
        outcome = analyser.analyse(run)
    except Exception as exc:
        if not flag_defects:
            raise
        outcome = RunAnalysis.failed(run.run_id, run.kind, f"{type(exc).__name__}: {exc}")
        analyser.knowledge.analysed_runs[run.run_id] = outcome
    changes = knowledge_changes(before, analyser.knowledge)
    try:
        record = AnalysisRecord(
            outcome=outcome,
            changes=changes,
            order=list(analyser.knowledge.analysed_runs).index(run.run_id),
            software_version=software_version(),
            inputs_sha256=inputs_sha256(run),
        )
        text = record_text(record)
    except (TypeError, ValueError):  # what the record cannot hold: a defect, never the run's loss
        if not flag_defects:
            raise
        text = ""
    return outcome, changes, text


def knowledge_snapshot(knowledge: CampaignKnowledge) -> dict[str, Any]:
    """Each field's object, and a shallow copy of each list or dict, to compare with afterwards."""
    snapshot = {}
    for field in dataclasses.fields(knowledge):
        value = getattr(knowledge, field.name)
        copy = list(value) if isinstance(value, list) else dict(value) if isinstance(value, dict) else None
        snapshot[field.name] = (value, copy)
    return snapshot


def knowledge_changes(before: dict[str, Any], knowledge: CampaignKnowledge) -> KnowledgeChanges:
    """What changed in ``knowledge`` since ``before`` (:func:`knowledge_snapshot`)."""
    changes: KnowledgeChanges = {}
    for name, (old, copy) in before.items():
        new = getattr(knowledge, name)
        if new is not old:
            changes[name] = ("set", new)
        elif isinstance(new, list) and not _same_items(new, copy):
            kept = len(new) > len(copy) and _same_items(new[: len(copy)], copy)
            changes[name] = ("extend", new[len(copy) :]) if kept else ("set", new)
        elif isinstance(new, dict):
            updated = {key: value for key, value in new.items() if key not in copy or copy[key] is not value}
            if updated:
                changes[name] = ("update", updated)
    return changes


def _same_items(items: list[Any], before: list[Any]) -> bool:
    """The same objects in the same order: by identity, as the knowledge keeps results it never
    changes in place (results hold arrays, which ``==`` would compare element by element)."""
    return len(items) == len(before) and all(a is b for a, b in zip(items, before, strict=True))


def apply_changes(knowledge: CampaignKnowledge, changes: KnowledgeChanges) -> None:
    """Apply what :func:`knowledge_changes` found to another copy of the knowledge (the bench's copy
    of the analysis process's, or the campaign's before its first run when records are read)."""
    for name, (how, value) in changes.items():
        if how == "set":
            setattr(knowledge, name, value)
        elif how == "extend":
            getattr(knowledge, name).extend(value)
        else:
            getattr(knowledge, name).update(value)


@dataclass(frozen=True)
class StoredAnalysis:
    """A campaign's analysis as its records give it: the ``knowledge`` they establish, each run's
    analysis in the order asked (``runs``), and the software versions that made them."""

    knowledge: CampaignKnowledge
    runs: tuple[RunAnalysis, ...]
    software_versions: tuple[str, ...]


def stored_analysis(runs: Iterable[RunView], knowledge: CampaignKnowledge) -> StoredAnalysis | str:
    """The analysis the records of ``runs`` (those a campaign analyses, in order) give, applied to
    ``knowledge`` (the campaign's before its first run); or why they cannot give it: a run without a
    record, or one this version cannot read. Records are applied in the order they were made."""
    runs = list(runs)
    records = []
    for run in runs:
        text = run.analysis_record
        if text is None:
            return f"run {run.run_id} has no stored analysis"
        try:
            records.append(parse_record(text))
        except TypedFormatError as err:
            return f"the stored analysis of run {run.run_id} cannot be read: {err}"
        if records[-1].outcome.run_id != run.run_id:
            return f"the stored analysis of run {run.run_id} is of run {records[-1].outcome.run_id}"
    for record in sorted(records, key=lambda r: r.order):
        apply_changes(knowledge, record.changes)
    missing = [run.run_id for run in runs if run.run_id not in knowledge.analysed_runs]
    if missing:
        return f"the stored analyses do not hold run {missing[0]}'s"
    return StoredAnalysis(
        knowledge=knowledge,
        runs=tuple(knowledge.analysed_runs[run.run_id] for run in runs),
        software_versions=tuple(dict.fromkeys(r.software_version for r in records)),
    )


def inputs_sha256(value: object) -> str:
    """The SHA-256 of what an analysis read (its :class:`~bench.app.run_analysis.RunInputs`), by
    value (:mod:`bench.app.value_digest`): every array's type, shape and bytes, every other value's
    value, field by field in order."""
    return value_sha256(value)
