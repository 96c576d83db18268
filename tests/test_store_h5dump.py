"""HDF5 1.10's h5dump (Debian hdf5-tools) reads a campaign file, and what it shows is exactly the
layout documented in docs/hdf5.md: every documented object with its type, and nothing undocumented."""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from bench.store import CampaignWriter
from sequences.channels import Channel, Role
from sequences.points import PointAttempt
from sequences.runs import EventKind

DOC = Path(__file__).resolve().parents[1] / "docs" / "hdf5.md"
H5DUMP = shutil.which("h5dump")
pytestmark = pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")

_ATOMIC = {
    "H5T_IEEE_F64LE": "f8",
    "H5T_IEEE_F32LE": "f4",
    "H5T_STD_I64LE": "i8",
    "H5T_STD_I32LE": "i4",
    "H5T_STD_U32LE": "u4",
    "H5T_STD_U16LE": "u2",
    "H5T_STD_U8LE": "u1",
}


@dataclass
class DumpedObject:
    """One group, dataset or attribute as h5dump shows it."""

    kind: str  # group, dataset, attribute
    dtype: str = ""  # f8, str, compound(name:type ...), ...
    space: str = ""  # scalar, simple, unlimited
    filters: list[str] = field(default_factory=list)


def _datatype(block: list[str]) -> str:
    """A DATATYPE block's type: an atomic code, ``str`` or ``compound(name:type ...)``."""
    head = block[0]
    if head.startswith("H5T_STRING"):
        return "str"
    if head.startswith("H5T_COMPOUND"):
        fields, pending = [], ""
        for line in block[1:]:
            if line.startswith("H5T_STRING"):
                pending = "str"
            elif m := re.fullmatch(r'\} "(\w+)";', line):
                fields.append(f"{m[1]}:{pending}")
            elif m := re.fullmatch(r'(H5T_\w+) "(\w+)";', line):
                fields.append(f"{m[2]}:{_ATOMIC.get(m[1], m[1])}")
        return f"compound({' '.join(fields)})"
    return _ATOMIC.get(head, head)


def parse_h5dump(text: str) -> dict[str, DumpedObject]:
    """Objects of ``h5dump -H -p`` output by path (attributes as ``path@name``)."""
    objects: dict[str, DumpedObject] = {}
    stack: list[str | None] = []  # the object each open brace belongs to (None: a sub-block)
    lines = iter(line.strip() for line in text.splitlines())
    for line in lines:
        current = next((p for p in reversed(stack) if p is not None), None)
        if m := re.fullmatch(r'(GROUP|DATASET|ATTRIBUTE) "(.*)" \{', line):
            kind, name = m[1].lower(), m[2]
            if kind == "attribute":
                path = f"{current}@{name}"
            elif name == "/":
                path = "/"
            else:
                path = f"{current.rstrip('/')}/{name}"
            objects[path] = DumpedObject(kind)
            stack.append(path)
        elif line.startswith("DATATYPE"):
            block = [line.removeprefix("DATATYPE").strip()]
            depth = block[0].count("{") - block[0].count("}")
            while depth:
                block.append(next(lines))
                depth += block[-1].count("{") - block[-1].count("}")
            objects[current].dtype = _datatype(block)
        elif line.startswith("DATASPACE"):
            objects[current].space = (
                "scalar" if "SCALAR" in line else "unlimited" if "H5S_UNLIMITED" in line else "simple"
            )
        elif "DEFLATE" in line or "SHUFFLE" in line:
            objects[current].filters.append("gzip" if "DEFLATE" in line else "shuffle")
        elif line.endswith("{"):
            stack.append(None)
        elif line == "}":
            stack.pop()
    return objects


@dataclass(frozen=True)
class Documented:
    pattern: re.Pattern[str]
    text: str
    kind: str
    types: tuple[str, ...]


def documented_layout() -> list[Documented]:
    """The ``layout`` block of docs/hdf5.md, one entry per line."""
    block = re.search(r"```layout\n(.*?)```", DOC.read_text(), re.S)
    assert block, "docs/hdf5.md has no layout block"
    entries = []
    for line in block[1].splitlines():
        path, kind, *rest = line.split()
        regex = re.escape(path).replace(r"\.\.\.", ".+")
        regex = re.sub(r"<\w+>", r"[^/@]+", regex)
        entries.append(Documented(re.compile(regex), path, kind, tuple(rest)))
    return entries


def _matches(doc: Documented, obj: DumpedObject) -> bool:
    """Whether the dumped object is what the documented line says (kind and type)."""
    if doc.kind == "any":
        return True
    plain = {  # kinds whose object has no type listed
        "group": obj.kind == "group",
        "bytes": obj.kind == "dataset" and obj.dtype == "u1" and obj.space == "simple" and obj.filters == [],
    }
    if doc.kind in plain:
        return plain[doc.kind]
    if doc.kind == "table":
        return (
            obj.kind == "dataset"
            and obj.dtype == f"compound({' '.join(doc.types)})"
            and obj.space == "unlimited"
            and obj.filters == []
        )
    if doc.kind == "channel":
        return (
            obj.kind == "dataset"
            and obj.dtype in doc.types[0].split("|")
            and obj.space == "unlimited"
            and obj.filters == ["shuffle", "gzip"]
        )
    if doc.kind == "number":
        return obj.kind == "attribute" and obj.dtype in _ATOMIC.values()
    # text: a scalar dataset of one string; else an attribute of the type named
    kind, dtype = ("dataset", "str") if doc.kind == "text" else ("attribute", doc.kind)
    return obj.kind == kind and obj.space == "scalar" and obj.dtype == dtype


@pytest.fixture(scope="module")
def dumped(tmp_path_factory) -> dict[str, DumpedObject]:
    """h5dump's view of a campaign file with one of everything the schema has."""
    path = tmp_path_factory.mktemp("h5dump") / "campaign.h5"
    writer = CampaignWriter.create(
        path, software_version="0.1.0", config_toml="", sequence_toml="", sequence_name="smoke.toml"
    )
    writer.add_event(EventKind.PROMPT, "2.4 bar", value=2.4)
    channels = [
        Channel("sample", "1", dtype="u4"),
        Channel("seq", "1", dtype="u4"),
        Channel("fz_wfs_n", "N", role=Role.WFS_FZ),
        Channel("z_base_m", "m", role=Role.BENCH_DISPLACEMENT),
        Channel("status", "1", dtype="u2"),
    ]
    run = writer.begin_run(
        "001",
        kind="free_run",
        step={"type": "free_run"},
        conditions={},
        channels=channels,
        sample_rate_hz=1e3,
    )
    n = 2000
    run.append(
        {
            "sample": np.arange(n),
            "seq": np.arange(n),
            "fz_wfs_n": np.ones(n),
            "z_base_m": np.zeros(n),
            "status": np.zeros(n, dtype=np.uint16),
        }
    )
    run.add_point(PointAttempt(0, 5.0, 1.0, 0, 100, 1900, 2000))
    run.add_event("state", "running")
    run.set_link_counters({"frames_ok": n, "gaps": 0})
    run.finish("complete")
    run.write_results("free_run", {"m_comp_kg": 12.0, "fit": {"freqs_hz": np.arange(5.0), "notes": ["ok"]}})
    run.write_analysis_record('{"format": 1}')  # the store keeps the text; its reader checks it
    run.write_figure("shaker_2p5bar", b"\x89PNG\r\n\x1a\n not drawn", "0" * 64)  # kept as bytes
    replay = writer.begin_run(  # a road replay: its drive attribute
        "002",
        kind="road_replay",
        step={"type": "road_replay"},
        conditions={},
        channels=channels[2:4],
        sample_rate_hz=1e3,
        drive={"source": "drive.csv column 'z [mm]'", "sha256": "0" * 64, "crc32": "00000000"},
    )
    replay.finish("aborted", "aborted by the operator")
    writer.close()
    out = subprocess.run(
        [H5DUMP, "-H", "-p", str(path)], capture_output=True, text=True, timeout=60, check=True
    )
    return parse_h5dump(out.stdout)


def test_h5dump_shows_every_documented_object_with_its_type(dumped):
    for doc in documented_layout():
        found = {p: o for p, o in dumped.items() if doc.pattern.fullmatch(p)}
        assert found, f"docs/hdf5.md documents {doc.text}, h5dump shows none"
        wrong = {p: o for p, o in found.items() if not _matches(doc, o)}
        assert not wrong, f"{doc.text} documented as {doc.kind} {' '.join(doc.types)}, h5dump shows {wrong}"


def test_h5dump_shows_nothing_undocumented(dumped):
    layout = documented_layout()
    undocumented = [p for p in dumped if not any(d.pattern.fullmatch(p) for d in layout)]
    assert not undocumented


def test_parser_reads_what_it_is_checked_on(dumped):
    """The parser itself: known objects come out with the expected shape (guards the tests above
    against a parser that sees nothing)."""
    assert dumped["/runs/001/channels/sample"] == DumpedObject(
        "dataset", "u4", "unlimited", ["shuffle", "gzip"]
    )
    assert dumped["/@schema_version"] == DumpedObject("attribute", "i8", "scalar")
    assert dumped["/runs/001/results/free_run/fit/freqs_hz"].dtype == "f8"
    assert dumped["/runs/001/points"].dtype.startswith("compound(index:i8 freq_hz:f8")
    assert len(dumped) > 40
