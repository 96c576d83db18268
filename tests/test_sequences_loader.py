"""Sequence files: every malformed file is refused with the file, the key and the reason, and every
problem of a file is reported at once."""

import textwrap
import tomllib

import pytest

from sequences import BenchLimits, SequenceError, SineDwell, load_sequence, parse_sequence
from sequences.toml_text import toml_error_where

LIMITS = BenchLimits()
HEADER = '[sequence]\nname = "t"\ndescription = ""\n'


def _file(tmp_path, body: str, header: str = HEADER):
    path = tmp_path / "campaign.toml"
    path.write_text(header + textwrap.dedent(body), encoding="utf-8")
    return path


def _refused(path) -> SequenceError:
    with pytest.raises(SequenceError) as info:
        load_sequence(path, LIMITS)
    assert info.value.source == str(path)
    return info.value


def test_a_good_file_loads(tmp_path):
    path = _file(
        tmp_path,
        """
        [[steps]]
        type = "hydraulics"
        level = "low"

        [[steps]]
        type = "hydraulics"
        level = "high"

        [[steps]]
        type = "sine_dwell"
        freq_hz = 40
        amplitude_mm = 2
        """,
    )
    sequence = load_sequence(path, LIMITS)
    assert sequence.name == "t" and sequence.source == str(path)
    assert sequence.steps[2] == SineDwell(40.0, 2.0)
    assert isinstance(sequence.steps[2].freq_hz, int)  # TOML integers are numbers too


DWELL = '[[steps]]\ntype = "tare"\n\n[[steps]]\ntype = "sine_dwell"\nfreq_hz = 40\n'


@pytest.mark.parametrize(
    ("body", "key", "text"),
    [
        (DWELL + "amplitude_mm = 60\n", "steps[1].amplitude_mm", "60 mm is above the 25 mm stroke"),
        (DWELL + "amplitude_mm = -1\n", "steps[1].amplitude_mm", "(allowed 0 < amplitude_mm <= 25 mm)"),
        (
            DWELL.replace("40", "250") + "amplitude_mm = 1\n",
            "steps[1].freq_hz",
            "250 Hz is above the bench's highest frequency (allowed 0.1 <= freq_hz <= 100 Hz)",
        ),
        (
            DWELL + "amplitude_mm = 1\namplitude = 2\n",
            "steps[1].amplitude",
            "unknown key for a sine_dwell step",
        ),
        (DWELL + 'amplitude_mm = "2"\n', "steps[1].amplitude_mm", "expected a number, got '2' (str)"),
        (DWELL + "amplitude_mm = true\n", "steps[1].amplitude_mm", "expected a number, got True (bool)"),
        (DWELL + "amplitude_mm = 1979-05-27\n", "steps[1].amplitude_mm", "expected a number"),
        (DWELL + "amplitude_mm = nan\n", "steps[1].amplitude_mm", "nan is not a finite number"),
        (DWELL + "amplitude_mm = inf\n", "steps[1].amplitude_mm", "inf is not a finite number"),
        (
            DWELL + "amplitude_mm = 1\nrequested_amplitude_mm = 2\n",
            "steps[1].requested_amplitude_mm",
            "unknown key",
        ),
        (DWELL, "steps[1].amplitude_mm", "missing: a sine_dwell step needs amplitude_mm"),
        ('[[steps]]\ntype = "sine_dwel"\n', "steps[0].type", "unknown step type 'sine_dwel'; use one of"),
        ('[[steps]]\ntype = ["sine_dwell"]\n', "steps[0].type", "unknown step type ['sine_dwell']; use"),
        ("[[steps]]\ntype = {a = 1}\n", "steps[0].type", "unknown step type {'a': 1}; use one of"),
        ("[[steps]]\nlevel = 1\n", "steps[0].type", "missing: a step needs type"),
        ('[[steps]]\nkind = "sine_dwell"\n', "steps[0].type", "missing: a step needs type, one of"),
        (
            '[[steps]]\ntype = "dwell_grid"\nfreqs_hz = []\namplitudes_mm = [1]\n',
            "steps[0].freqs_hz",
            "the grid has no values",
        ),
        (
            '[[steps]]\ntype = "dwell_grid"\nfreqs_hz = 10\namplitudes_mm = [1]\n',
            "steps[0].freqs_hz",
            "expected a list of numbers, got 10",
        ),
        (
            '[[steps]]\ntype = "free_run"\nfreqs_hz = [10, 70]\namplitudes_mm = [5]\n',
            "steps[0].amplitudes_mm[0]",
            "5 mm at 70 Hz needs a peak velocity of 2199 mm/s, beyond the bench's 1600 mm/s",
        ),
        ('[[steps]]\ntype = "tare"\n[extra]\nx = 1\n', "extra", "unknown key; allowed: sequence, steps"),
        ('[[steps]]\ntype = "tare"\ncolour = "red"\n', "steps[0].colour", "unknown key for a tare step"),
        ('[[steps]]\ntype = "hydraulics"\nlevel = "max"\n', "steps[0].level", "'max' is not one of"),
    ],
)
def test_bad_values_are_refused_with_key_and_range(tmp_path, body, key, text):
    error = _refused(_file(tmp_path, body))
    assert error.key == key
    assert text in error.message
    assert str(error).startswith(f"{tmp_path / 'campaign.toml'}: {key}: ")


@pytest.mark.parametrize(
    ("header", "key", "text"),
    [
        ('[sequence]\nname = ""\n', "sequence.name", "non-empty string"),
        (
            '[sequence]\nname = "x"\nauthor = "me"\n',
            "sequence.author",
            "unknown key; allowed: name, description",
        ),
        ("", "sequence", "missing [sequence] table"),
        ("[sequence]\nname = 3\n", "sequence.name", "got 3"),
    ],
)
def test_bad_headers_are_refused(tmp_path, header, key, text):
    error = _refused(_file(tmp_path, '[[steps]]\ntype = "tare"\n', header=header))
    assert error.key == key and text in error.message


def test_a_misspelt_sequence_table_is_one_unknown_key_and_nothing_more(tmp_path):
    """``[sequenc]``: its unknown key names it and the allowed ``sequence``; neither a missing table
    nor an empty ``sequence.name`` is reported on top."""
    error = _refused(_file(tmp_path, '[[steps]]\ntype = "tare"\n', header='[sequenc]\nname = "x"\n'))
    unknown = ("sequenc", "unknown key; allowed: sequence, steps, metadata")
    assert [(p.key, p.message) for p in error.problems] == [unknown]


@pytest.mark.parametrize("text", ["", "\n\n", "# only a comment\n"])
def test_empty_files_are_refused(tmp_path, text):
    path = tmp_path / "empty.toml"
    path.write_text(text)
    error = _refused(path)
    assert "empty file" in str(error) and error.key == ""


def test_duplicate_key_names_the_line_and_the_key(tmp_path):
    path = _file(
        tmp_path,
        """
        [[steps]]
        type = "tare"

        [[steps]]
        type = "sine_dwell"
        freq_hz = 40
        amplitude_mm = 1
        amplitude_mm = 2
        """,
    )
    error = _refused(path)
    assert error.key == "steps[1].amplitude_mm"
    assert error.message.startswith("line 12: duplicate key: it is already defined above")


def test_duplicate_table_is_named(tmp_path):
    error = _refused(_file(tmp_path, '[sequence]\nname = "again"\n'))
    assert error.key == "sequence" and "duplicate key" in error.message


def test_toml_syntax_error_names_the_line(tmp_path):
    error = _refused(_file(tmp_path, '[[steps]]\ntype = "tare"\nlevel = \n'))
    assert error.key == "steps[0].level" and error.message.startswith("line 6: not valid TOML: Invalid value")


def test_missing_and_unreadable_files(tmp_path):
    error = _refused(tmp_path / "nowhere.toml")
    assert "cannot read the sequence file" in str(error)
    binary = tmp_path / "campaign.toml"
    binary.write_bytes(b'[sequence]\nname = "\xff"\n')
    assert "not UTF-8 text" in str(_refused(binary))


def test_all_problems_of_a_file_in_file_order(tmp_path):
    path = _file(
        tmp_path,
        """
        [[steps]]
        type = "sine_dwell"
        freq_hz = 400
        amplitude_mm = 1
        colour = "red"

        [[steps]]
        type = "warp"

        [[steps]]
        type = "sweep"
        start_hz = 1
        end_hz = 30
        duration_s = 60
        amplitude_mm = true
        """,
        header='[sequence]\nname = ""\n',
    )
    error = _refused(path)
    assert [p.key for p in error.problems] == [
        "sequence.name",
        "steps[0].colour",
        "steps[0].freq_hz",
        "steps[1].type",
        "steps[2].amplitude_mm",
    ]
    assert str(error).splitlines()[0] == str(error.problems[0])
    assert "and 4 more" in str(error)


def test_parse_sequence_takes_text_and_a_source_name():
    sequence = parse_sequence(HEADER + '[[steps]]\ntype = "tare"\n', "inline", LIMITS)
    assert sequence.source == "inline" and len(sequence.steps) == 1


@pytest.mark.parametrize("text", [HEADER, "steps = []\n" + HEADER])
def test_a_file_without_steps_is_refused(text):
    with pytest.raises(SequenceError) as info:
        parse_sequence(text, "nosteps.toml", LIMITS)
    assert info.value.key == "steps" and "at least one [[steps]] table" in info.value.message


def test_a_toml_error_names_the_key_in_its_table_arrays_of_tables_indexed():
    """One reading of tomllib's errors for every TOML file of the product (sequences, bench
    configurations, answers files)."""
    text = (
        '[source]\nname = "x"\n[[runs]]\n[[runs.points]]\nb = 1\n'
        "[[runs]]\n[[runs.points]]\n[[runs.points]]\nc = 1  # x\nc = 2\n"
    )
    with pytest.raises(tomllib.TOMLDecodeError) as refused:
        tomllib.loads(text)
    assert toml_error_where(text, str(refused.value)) == (
        "runs[1].points[1].c",
        "line 10: duplicate key: it is already defined above in the same table (Cannot overwrite a value)",
    )
    assert toml_error_where("a = \n", "Invalid value (at line 1, column 5)") == (
        "a",
        "line 1: not valid TOML: Invalid value",
    )
