"""The test metadata as people read it: one labelled row per field given, in the order of
:data:`~sequences.metadata.METADATA_FIELDS`, for the text of ``wfsbench analyze`` and ``show`` and
the report's heading. Fields not given are left out; a campaign that gives none says so.
"""

from __future__ import annotations

from collections.abc import Mapping
from html import escape

from sequences.metadata import LABELS, METADATA_FIELDS

#: What a campaign without any metadata shows in place of the rows.
NONE_GIVEN = "none given"


def metadata_rows(metadata: Mapping[str, str]) -> list[tuple[str, str]]:
    """(label, value) of every field given, in the fields' order."""
    return [(LABELS[name], metadata[name]) for name in METADATA_FIELDS if metadata.get(name)]


def metadata_lines(metadata: Mapping[str, str], indent: str = "  ") -> list[str]:
    """The rows as aligned text lines (a value of several lines continues under its first);
    ``[indent + "none given"]`` when no field is given."""
    rows = metadata_rows(metadata)
    if not rows:
        return [f"{indent}{NONE_GIVEN}"]
    width = max(len(label) for label, _ in rows)
    lines = []
    for label, value in rows:
        first, *rest = value.splitlines() or [""]
        lines.append(f"{indent}{label:<{width}}  {first}")
        lines += [f"{indent}{'':<{width}}  {line}" for line in rest]
    return lines


def metadata_html(metadata: Mapping[str, str]) -> str:
    """The rows as a small table for a page's heading (values escaped; the lines of a value kept)."""
    rows = metadata_rows(metadata)
    if not rows:
        return f'<p class="metadata">Test metadata: {NONE_GIVEN}.</p>'
    body = "".join(
        f"<tr><th>{escape(label)}</th><td>{escape(value).replace(chr(10), '<br>')}</td></tr>"
        for label, value in rows
    )
    return f'<table class="metadata">{body}</table>'
