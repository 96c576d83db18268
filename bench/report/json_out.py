"""The analysis JSON as text and back: :class:`~bench.report.analysis_document.AnalysisDocument`
laid out by its types (:mod:`bench.store.typed`) as indented JSON, schema ``wfs-bench-analysis``
(docs/analysis-json.md lists every key with its unit), and such text read back into the document by
the same types, so that a reader gets attributes, not keys. The JSON holds no NaN or infinity: a
number the data does not give is ``null``, and text that holds one anyway is refused.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping

from bench.analysis.campaign import CampaignAnalysis
from bench.report.analysis_document import SCHEMA, VERSION, AnalysisDocument
from bench.store.typed import from_json_tree, to_json_tree

#: Where the messages of :func:`document_text` and :func:`read_analysis_json` start a place.
_ROOT = "document"


def analysis_json_text(analysis: CampaignAnalysis, results_names: Mapping[str, str] | None = None) -> str:
    """``analysis`` as the JSON ``wfsbench analyze --json`` prints; ``results_names``: run id -> the
    name its results were stored under (from :func:`~bench.app.analyze.store_reanalysis`)."""
    return document_text(AnalysisDocument.of(analysis, results_names))


def document_text(document: AnalysisDocument) -> str:
    """``document`` as indented JSON text; ValueError naming the place of a number that is not
    finite (the document's builders turn each into None: one left is a defect, not data)."""
    _refuse_non_finite(document, _ROOT)
    return json.dumps(to_json_tree(document, AnalysisDocument, _ROOT), indent=2, allow_nan=False)


def read_analysis_json(text: str) -> AnalysisDocument:
    """The document :func:`document_text` wrote, by its types: ``read_analysis_json(document_text(d))
    == d``. ValueError saying why for text that is not JSON, of another schema or version than this
    software writes, not laid out as the document's types ask (a
    :class:`~bench.store.typed.TypedFormatError` naming the place: ``document.shaker[0].free_run``),
    or holding a number that is not finite."""
    try:
        tree = json.loads(text, parse_constant=_refuse_constant)
    except json.JSONDecodeError as err:
        raise ValueError(f"not JSON: {err}") from err
    if not isinstance(tree, dict):
        raise ValueError(f"not the analysis JSON: a {type(tree).__name__}, not an object")
    if tree.get("schema") != SCHEMA:
        raise ValueError(f"not the analysis JSON: schema {tree.get('schema')!r}, not {SCHEMA!r}")
    if tree.get("version") != VERSION:
        raise ValueError(f"{SCHEMA} version {tree.get('version')!r}: this version reads {VERSION}")
    document = from_json_tree(tree, AnalysisDocument, _ROOT)
    _refuse_non_finite(document, _ROOT)
    return document


def _refuse_constant(name: str) -> float:
    """``json.loads``'s hook for ``NaN`` and ``Infinity``, which are no JSON."""
    raise ValueError(f"not JSON: {name} (the analysis JSON holds no NaN or infinity)")


def _refuse_non_finite(value: object, where: str) -> None:
    """ValueError naming the first float in ``value`` (a document or a part of it) that is not
    finite: the codec would write it as a string, where the JSON holds a number or null."""
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"{where}: {value!r} is not a finite number (one the data does not give is null)")
    if dataclasses.is_dataclass(value):
        for field in dataclasses.fields(value):
            _refuse_non_finite(getattr(value, field.name), f"{where}.{field.name}")
    elif isinstance(value, tuple):
        for i, item in enumerate(value):
            _refuse_non_finite(item, f"{where}[{i}]")
    elif isinstance(value, dict):
        for key, item in value.items():
            _refuse_non_finite(item, f"{where}[{key!r}]")
