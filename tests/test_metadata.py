"""The test metadata given in the bench configuration, the sequence file and on the command line:
each later source wins key by key, and garbage (an unknown key, a value that is not text, a date
that is not YYYY-MM-DD) is refused naming the file (or the option) and the key."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from bench.app.plan import plan_campaign
from bench.cli.exit_codes import ExitCode
from bench.cli.main import build_parser, main
from bench.cli.metadata import META_HELP
from bench.config import ConfigError, default_bench_config, measured_bench, parse_bench_config
from sequences import SequenceError, dump_sequence, parse_sequence, shipped_file
from sequences.limits import BenchLimits
from sequences.metadata import METADATA_FIELDS, merged

SEQUENCE = '[sequence]\nname = "m"\n\n[[steps]]\ntype = "sine_dwell"\nfreq_hz = 20\namplitude_mm = 1\n'

#: Garbage for one [metadata] table: the line, the key named, the reason's words.
GARBAGE = [
    ('tyre_idd = "T-1"', "metadata.tyre_idd", "unknown key; allowed: bench_id, sensor_serial"),
    ("tyre_id = 815", "metadata.tyre_id", "expected text (a string in quotes), got 815 (int)"),
    ("operator = true", "metadata.operator", "got True (bool)"),
    ('notes = ["a", "b"]', "metadata.notes", "(list)"),
    ("bench_id = 2026-03-01", "metadata.bench_id", "(date)"),
    ('sensor_calibration_date = "01.03.2026"', "metadata.sensor_calibration_date", "not a date written"),
    ('sensor_calibration_date = "2026-02-30"', "metadata.sensor_calibration_date", "no date of the calendar"),
    ('sensor_calibration_date = "20260301"', "metadata.sensor_calibration_date", "YYYY-MM-DD"),
    ("sensor_calibration_date = 2026-03-01T10:00:00", "metadata.sensor_calibration_date", "a date and time"),
]


@pytest.mark.parametrize(("line", "key", "reason"), GARBAGE)
def test_garbage_in_the_configurations_metadata_is_refused_with_file_and_key(line, key, reason):
    with pytest.raises(ConfigError) as info:
        parse_bench_config(f"[metadata]\n{line}\n", "lab.toml")
    (problem,) = info.value.problems
    assert problem.startswith(f"lab.toml: {key}: ") and reason in problem, problem


@pytest.mark.parametrize(("line", "key", "reason"), GARBAGE)
def test_garbage_in_the_sequences_metadata_is_refused_with_file_and_key(line, key, reason):
    with pytest.raises(SequenceError) as info:
        parse_sequence(f"{SEQUENCE}\n[metadata]\n{line}\n", "seq.toml", BenchLimits())
    assert (info.value.source, info.value.key) == ("seq.toml", key) and reason in info.value.message


def test_every_problem_of_the_table_is_named_and_a_table_is_required():
    with pytest.raises(ConfigError) as info:
        parse_bench_config(
            '[metadata]\ntyre_id = 1\nsensor_calibration_date = "1.3."\noperator = "A"\n', "l.toml"
        )
    assert [p.split(": ")[1] for p in info.value.problems] == [
        "metadata.tyre_id",
        "metadata.sensor_calibration_date",
    ]
    with pytest.raises(SequenceError, match="metadata: must be a table of texts"):
        parse_sequence(f'metadata = "x"\n{SEQUENCE}', "seq.toml", BenchLimits())


def test_a_good_table_reads_and_writes_back_and_shapes_no_measurement():
    text = textwrap.dedent(
        '''
        [metadata]
        bench_id = "shaker-1"
        sensor_calibration_date = 2026-03-01
        notes = """two
        lines, ünïcode"""
        '''
    )
    config = parse_bench_config(text, "lab.toml")
    assert config.metadata == {
        "bench_id": "shaker-1",
        "sensor_calibration_date": "2026-03-01",
        "notes": "two\nlines, ünïcode",
    }
    assert parse_bench_config(config.to_toml(), "again.toml").metadata == config.metadata
    assert measured_bench(config) == measured_bench(default_bench_config())  # a resume does not compare it
    sequence = parse_sequence(f"{SEQUENCE}\n{text}", "seq.toml", BenchLimits())
    assert sequence.metadata == config.metadata
    assert parse_sequence(dump_sequence(sequence), "dumped.toml", BenchLimits()).metadata == sequence.metadata


def test_the_sequence_wins_over_the_configuration_and_meta_over_both(tmp_path: Path):
    (tmp_path / "lab.toml").write_text(
        '[metadata]\nbench_id = "B1"\noperator = "config"\nnotes = "from config"\n'
    )
    (tmp_path / "seq.toml").write_text(f'{SEQUENCE}\n[metadata]\noperator = "sequence"\ntyre_id = "T-1"\n')
    plan = plan_campaign(
        tmp_path / "seq.toml", tmp_path / "lab.toml", metadata={"tyre_id": "T-2", "notes": ""}
    )
    assert plan.metadata == merged(
        {"bench_id": "B1", "operator": "sequence", "tyre_id": "T-2", "notes": ""}
    )  # notes= on the command line clears the configuration's
    assert list(plan.metadata) == list(METADATA_FIELDS)
    assert plan.with_metadata({"operator": "UI"}).metadata["operator"] == "UI"


def test_meta_on_the_command_line_collects_its_keys_and_refuses_garbage(capsys):
    parser = build_parser()
    args = parser.parse_args(
        [
            "run",
            "s.toml",
            "--out",
            "a.h5",
            "--meta",
            "operator=A. Person",
            "--meta",
            "notes=x=y",
            "--meta",
            "notes=",
        ]
    )
    assert args.meta == {"operator": "A. Person", "notes": ""}
    assert parser.parse_args(["run", "s.toml", "--out", "a.h5"]).meta == {}
    for bad, words in (
        ("tyre_idd=1", "tyre_idd: unknown key; allowed: bench_id"),
        ("operator", "'operator': expected KEY=VALUE, one of bench_id"),
        ("sensor_calibration_date=2026-13-01", "sensor_calibration_date: '2026-13-01' is no date of"),
    ):
        for command in (
            ["run", "s.toml", "--out", "a.h5"],
            ["import-csv", "m.toml", "--out", "a.h5"],
            ["demo"],
        ):
            with pytest.raises(SystemExit) as exit_info:
                main([*command, "--meta", bad])
            assert exit_info.value.code == ExitCode.INVALID
            assert f"error: argument --meta: {words}" in capsys.readouterr().err


def test_the_help_names_every_field_and_only_those():
    named = [word.strip(" ;,") for word in META_HELP.split(":")[1].split(";")[0].split(",")]
    assert [word.split(" ")[0] for word in named] == list(METADATA_FIELDS)


def test_the_shipped_configuration_documents_the_table_and_gives_nothing():
    config_path = Path(__file__).resolve().parents[1] / "configs" / "simulated_shaker.toml"
    text = config_path.read_text()
    assert all(f"# {name} = " in text for name in METADATA_FIELDS)
    assert parse_bench_config(text, str(config_path)).metadata == {}
    assert parse_sequence(shipped_file("smoke.toml").read_text(), "smoke", BenchLimits()).metadata == {}


def test_import_csv_records_the_configurations_metadata_with_meta_winning(tmp_path: Path):
    from bench.store import open_campaign
    from tests.test_csv_import import GOOD_CSV, MAPPING

    (tmp_path / "mapping.toml").write_text(MAPPING)
    (tmp_path / "free.csv").write_text(GOOD_CSV)
    (tmp_path / "lab.toml").write_text('[metadata]\nbench_id = "B1"\noperator = "config"\n')
    out = tmp_path / "imported.h5"
    args = [
        "import-csv",
        str(tmp_path / "mapping.toml"),
        "--out",
        str(out),
        "--bench",
        str(tmp_path / "lab.toml"),
    ]
    assert main([*args, "--meta", "operator=Ann", "--meta", "tyre_size=205/55 R16"]) == 0
    with open_campaign(out) as campaign:
        assert campaign.metadata == merged({"bench_id": "B1", "operator": "Ann", "tyre_size": "205/55 R16"})
        (run,) = campaign.runs
        assert run.metadata == {"bench_id": "B1", "operator": "Ann", "notes": ""}
