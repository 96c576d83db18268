"""Arrays nested hundreds of levels deep (tomllib runs out of stack on them; any walk of the data
would too) are the file's error, exit 3, naming the file, for every file the command line reads: a
sequence and a bench configuration (``check``, ``run``), an answers file (``run``), an import
mapping (``import-csv``)."""

from __future__ import annotations

import pytest

from bench.cli.exit_codes import ExitCode
from sequences.toml_text import MAX_NESTING, load_toml
from tests.commands import wfsbench
from tests.test_campaign_cli import SMOKE


def _nested(levels: int) -> str:
    return "[" * levels + "1" + "]" * levels


@pytest.mark.parametrize("levels", [MAX_NESTING, 500, 5000])
def test_load_toml_refuses_nesting_beyond_the_limit_as_a_toml_error(levels):
    import tomllib

    with pytest.raises(tomllib.TOMLDecodeError, match=r"^nested too deep: .* more than 32 levels"):
        load_toml(f"a = {_nested(levels)}\n")


def test_load_toml_reads_nesting_within_the_limit():
    assert load_toml(f"a = {_nested(MAX_NESTING - 2)}\n")["a"][0][0] is not None


@pytest.mark.parametrize(
    "kind", ["check sequence", "check bench", "run sequence", "run bench", "run answers", "mapping"]
)
def test_a_file_nested_too_deep_is_exit_3_naming_the_file(tmp_path, kind):
    levels = 500  # tomllib fails with a RecursionError
    deep = tmp_path / "deep.toml"
    sequence, bench = str(SMOKE), []
    if kind.endswith("sequence"):
        deep.write_text(
            f'[sequence]\nname = "deep"\n\n[[steps]]\ntype = "hydraulics"\nlevel = {_nested(levels)}\n'
        )
        sequence = str(deep)
    elif kind.endswith("bench"):
        deep.write_text(f'kind = "shaker"\n[limits]\nwfs_force_n = {_nested(levels)}\n')
        bench = ["--bench", str(deep)]
    elif kind == "run answers":
        deep.write_text(f"pressure = {_nested(levels)}\n")
    else:
        deep.write_text(f'[source]\nname = "deep"\nbench = {_nested(levels)}\n')
    if kind.startswith("check"):
        result = wfsbench("check", sequence, *bench)
    elif kind == "mapping":
        result = wfsbench("import-csv", str(deep), "--out", str(tmp_path / "imported.h5"))
    else:
        answers = ["--answers", str(deep)] if kind == "run answers" else []
        result = wfsbench("run", sequence, "--out", str(tmp_path / "run.h5"), *bench, *answers)
    assert result.returncode == ExitCode.INVALID, result.stderr
    assert result.stderr.startswith(f"error: {deep}: nested too deep: "), result.stderr
    assert "Traceback" not in result.stderr
    assert not list(tmp_path.glob("*.h5"))
