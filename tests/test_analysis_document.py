"""The analysis JSON is made from its types and read back into them (docs/analysis-json.md): the text
of a campaign's analysis reads back to an equal document, holds a number or null wherever its type
asks for a number (never NaN, infinity or a string), documents every key, and a reader refuses
another schema, another version and garbage, saying why. The codec under it writes a mapping of
strings as a JSON object and still reads the pairs of analysis records of format 3."""

from __future__ import annotations

import dataclasses
import json
import math
import re
import shutil
import types
import typing
from collections.abc import Iterator
from pathlib import Path

import h5py
import pytest

from bench.analysis.runs import nominal_free_run
from bench.app import analysis_record
from bench.app.analysis_record import RECORD_FORMAT, parse_record, record_text
from bench.app.analyze import analyze_campaign
from bench.models.benches import TyreModel
from bench.models.setup import BenchSetup
from bench.report import analysis_document
from bench.report.analysis_document import SCHEMA, VERSION, AnalysisDocument, FreeRunDoc, GivenDoc
from bench.report.json_out import analysis_json_text, document_text, read_analysis_json
from bench.store import open_campaign, typed
from bench.store.typed import TypedFormatError, from_json_tree, to_json_tree
from tests.campaign_files import paper_corner_runs, write_analysed_campaign
from tests.made_once import made_once
from tests.test_analysis_record import assert_same

ROOT = Path(__file__).resolve().parents[1]
#: The corner campaign other tests read too (tests/test_compensate.py): the shaker's free run and
#: three amplitudes at 2.5 bar, the post's free run and the four-post sweep, analysed and recorded.
CAR = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD)


@pytest.fixture(scope="module")
def corner_file(shared_folder) -> Path:
    return made_once(
        shared_folder, "corner-2.5-bar.h5", lambda path: write_analysed_campaign(path, paper_corner_runs(CAR))
    )


@pytest.fixture(scope="module")
def corner_text(corner_file) -> str:
    """The corner campaign's analysis JSON, as ``wfsbench analyze --json`` prints it."""
    return analysis_json_text(analyze_campaign(corner_file))


def document_types(cls: type = AnalysisDocument) -> Iterator[type]:
    """``cls`` and every document type its fields hold, each once (depth first)."""
    seen: list[type] = []

    def visit(hint: object) -> None:
        if dataclasses.is_dataclass(hint) and hint not in seen:
            seen.append(hint)
            for field_hint in typing.get_type_hints(hint).values():
                visit(field_hint)
        for arg in typing.get_args(hint):
            visit(arg)

    visit(cls)
    return iter(seen)


def sample(hint: object) -> object:
    """A value of every field of ``hint``, None nowhere and every array one item long: a document
    that holds each of its types."""
    args = typing.get_args(hint)
    if dataclasses.is_dataclass(hint):
        return hint(**{name: sample(h) for name, h in typing.get_type_hints(hint).items()})
    if typing.get_origin(hint) in (types.UnionType, typing.Union):
        (arm,) = [a for a in args if a is not type(None)]
        return sample(arm)
    if typing.get_origin(hint) is tuple:
        return tuple(sample(a) for a in (args[:1] if args[-1] is Ellipsis else args))
    if typing.get_origin(hint) is dict:
        return {"first": sample(args[1]), "second": sample(args[1])}
    return {float: 0.1 + 0.2, int: 7, bool: True, str: "text"}[hint]


def every_type_document() -> AnalysisDocument:
    """:func:`sample` of the whole document, of this schema and version."""
    return dataclasses.replace(sample(AnalysisDocument), schema=SCHEMA, version=VERSION)


def assert_laid_out(tree: object, hint: object, where: str = "document") -> None:
    """``tree`` is JSON as ``hint`` lays it out: an object's keys are its type's fields in order, a
    number is a finite number (no string), null only where the type allows it."""
    args = typing.get_args(hint)
    origin = typing.get_origin(hint)
    if dataclasses.is_dataclass(hint):
        hints = typing.get_type_hints(hint)
        assert isinstance(tree, dict) and list(tree) == list(hints), where
        for name, field_hint in hints.items():
            assert_laid_out(tree[name], field_hint, f"{where}.{name}")
    elif origin in (types.UnionType, typing.Union):
        if tree is None:
            assert type(None) in args, f"{where}: null"
        else:
            (arm,) = [a for a in args if a is not type(None)]
            assert_laid_out(tree, arm, where)
    elif origin is tuple:
        assert isinstance(tree, list), where
        item_hints = [args[0]] * len(tree) if args[-1] is Ellipsis else list(args)
        assert len(item_hints) == len(tree), where
        for i, (item, item_hint) in enumerate(zip(tree, item_hints, strict=True)):
            assert_laid_out(item, item_hint, f"{where}[{i}]")
    elif origin is dict:
        assert isinstance(tree, dict), where
        for key, item in tree.items():
            assert_laid_out(item, args[1], f"{where}[{key!r}]")
    elif hint is float:
        number = isinstance(tree, int | float) and not isinstance(tree, bool)
        assert number and math.isfinite(tree), f"{where}: {tree!r} is no finite number"
    else:
        assert type(tree) is hint, f"{where}: {tree!r} is no {hint}"


def test_a_campaigns_analysis_json_reads_back_to_the_same_document(corner_file, corner_text):
    doc = read_analysis_json(corner_text)
    assert doc == AnalysisDocument.of(analyze_campaign(corner_file))
    assert document_text(doc) == corner_text
    assert (doc.schema, doc.version) == (SCHEMA, VERSION) == ("wfs-bench-analysis", 3)
    (shaker,) = doc.shaker
    assert len(shaker.amplitudes) == 3 and len(shaker.amplitude_dependence) == 3
    assert doc.four_post is not None and doc.four_post.quarter_car.values
    assert {run.run_id for run in doc.runs} >= {"free", "post-free", "sweep"}


def test_a_document_holding_every_type_reads_back_equal():
    doc = every_type_document()
    assert read_analysis_json(document_text(doc)) == doc


@pytest.mark.parametrize("which", ["campaign", "every type"])
def test_the_json_holds_numbers_where_numbers_belong(which, corner_text):
    text = corner_text if which == "campaign" else document_text(every_type_document())
    assert "NaN" not in text and "Infinity" not in text
    assert_laid_out(json.loads(text), AnalysisDocument)


def test_a_number_the_data_does_not_give_is_null_and_a_non_finite_one_never_written():
    free = FreeRunDoc.of(nominal_free_run(12.0, "the configuration"))  # no free run: no residual
    assert free.nominal and free.m_comp_kg == 12.0
    assert free.residual_rms_n_per_m is None and free.m_comp_sigma_kg is None
    assert json.loads(json.dumps(to_json_tree(free, FreeRunDoc)))["residual_rms_n_per_m"] is None
    broken = dataclasses.replace(every_type_document(), given=GivenDoc(math.nan, 29.0))
    with pytest.raises(ValueError, match=r"document\.given\.sensor_mass_kg: nan is not a finite number"):
        document_text(broken)


def test_every_key_of_every_document_type_is_documented():
    text = (ROOT / "docs" / "analysis-json.md").read_text(encoding="utf-8")
    missing = [
        f"{cls.__name__}.{field.name}"
        for cls in document_types()
        for field in dataclasses.fields(cls)
        if not re.search(rf"[`.]{field.name}(\[\])?[`.]", text)  # `key`, `.key`, `key[]`, `key.member`
    ]
    assert missing == [], f"docs/analysis-json.md does not name {missing}"
    defined = {
        t
        for t in vars(analysis_document).values()
        if dataclasses.is_dataclass(t) and t.__module__ == analysis_document.__name__
    }
    assert set(document_types()) == defined  # the walk reaches every type of the document


@pytest.mark.parametrize(
    ("change", "why"),
    [
        (lambda tree: {**tree, "schema": "other"}, r"schema 'other', not 'wfs-bench-analysis'"),
        (lambda tree: {**tree, "version": 2}, r"wfs-bench-analysis version 2: this version reads 3"),
        (lambda tree: {k: v for k, v in tree.items() if k != "version"}, r"version None: this version"),
        (lambda tree: [tree], r"a list, not an object"),
        (lambda tree: {**tree, "status": 1}, r"document\.status: 1 is not a str"),
        (lambda tree: {**tree, "given": {"sensor_mass_kg": 3.8}}, r"document\.given: not a GivenDoc"),
        (
            lambda tree: {**tree, "given": {"sensor_mass_kg": "nan", "wheel_mass_kg": 29.0}},
            r"document\.given\.sensor_mass_kg: nan is not a finite number",
        ),
    ],
    ids=["schema", "version", "no version", "not an object", "a string", "a member missing", "nan string"],
)
def test_the_reader_refuses_another_schema_another_version_and_garbage(corner_text, change, why):
    text = json.dumps(change(json.loads(corner_text)))
    with pytest.raises(ValueError, match=why):
        read_analysis_json(text)


@pytest.mark.parametrize(
    ("text", "why"),
    [("{not json", r"not JSON: Expecting property name"), ('{"schema": NaN}', r"not JSON: NaN")],
)
def test_the_reader_refuses_text_that_is_not_json(text, why):
    with pytest.raises(ValueError, match=why):
        read_analysis_json(text)


def test_a_wrong_member_deep_in_the_document_is_named_by_its_place(corner_text):
    tree = json.loads(corner_text)
    tree["shaker"][0]["amplitudes"][1]["models"][0]["values"]["stiffness_n_per_m"] = "stiff"
    with pytest.raises(TypedFormatError, match=r"shaker\[0\]\.amplitudes\[1\]\.models\[0\]\.values\['stiff"):
        read_analysis_json(json.dumps(tree))


def test_the_codec_writes_a_mapping_of_strings_as_an_object_and_reads_the_old_pairs_too():
    hint = dict[str, float]
    values = {"stiffness_n_per_m": 3.9e5, "tread_mass_kg": 6.0}
    assert to_json_tree(values, hint) == values
    assert from_json_tree({"tread_mass_kg": 6.0, "stiffness_n_per_m": 3.9e5}, hint) == values
    assert from_json_tree([["stiffness_n_per_m", 3.9e5], ["tread_mass_kg", 6.0]], hint) == values
    assert list(from_json_tree(to_json_tree(values, hint), hint)) == list(values)  # in order
    with pytest.raises(TypedFormatError, match=r"neither an object nor a list of \[key, value\] pairs"):
        from_json_tree("stiff", hint)
    with pytest.raises(TypedFormatError, match=r"\['tread_mass_kg'\]: 'heavy' is not a float"):
        from_json_tree({"tread_mass_kg": "heavy"}, hint)
    with pytest.raises(TypeError, match=r"key 1\.5 of a mapping of strings"):
        to_json_tree({1.5: 1.0}, hint)
    assert to_json_tree({1.5: 2.0}, dict[float, float]) == [[1.5, 2.0]]  # other keys: pairs still
    with pytest.raises(TypedFormatError, match=r"not a list of \[key, value\] pairs"):
        from_json_tree({"1.5": 2.0}, dict[float, float])


def _pairs(value: object, hint: object, where: str) -> list[list[object]]:
    """The codec's layout of every mapping before records of format 4: ``[key, value]`` pairs."""
    key_hint, value_hint = typing.get_args(hint)
    return [[to_json_tree(k, key_hint, where), to_json_tree(v, value_hint, where)] for k, v in value.items()]


def test_analysis_records_of_format_3_still_read(corner_file, tmp_path, monkeypatch):
    """Each record of the corner campaign written again as format 3 wrote it (its mappings of
    strings as pairs): parsed, it is the format-4 record; the file's analysis is read from them."""
    assert RECORD_FORMAT == 4
    old = Path(shutil.copyfile(corner_file, tmp_path / "format-3.h5"))
    with open_campaign(corner_file) as campaign:
        texts = {run.run_id: run.analysis_record for run in campaign.runs if run.analysis_record}
    with monkeypatch.context() as patched:
        patched.setitem(typed._WRITERS, "mapping", _pairs)
        patched.setattr(analysis_record, "RECORD_FORMAT", 3)
        format_3 = {run_id: record_text(parse_record(text)) for run_id, text in texts.items()}
    for run_id, text in format_3.items():
        tree = json.loads(text)
        assert tree["format"] == 3
        (analysed,) = [change for change in tree["changes"] if change[0] == "analysed_runs"]
        assert isinstance(analysed[2], list)  # run id -> analysis as pairs, as format 3 has it
        assert_same(parse_record(text), parse_record(texts[run_id]), run_id)
    with h5py.File(old, "r+") as f:
        for run_id, text in format_3.items():
            del f[f"runs/{run_id}/analysis"]
            f[f"runs/{run_id}"].create_dataset("analysis", data=text, dtype=h5py.string_dtype())
    stored, read = analyze_campaign(corner_file), analyze_campaign(old)
    assert read.stored and read.source == stored.source
    assert_same(read.knowledge, stored.knowledge, "knowledge")
