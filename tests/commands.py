"""The ``wfsbench`` command as the tests run it: in this process (the command's entry point, its
standard streams captured), or where the process itself is under test (the console script, its
exit status, signals, a terminal) in a process of its own."""

from __future__ import annotations

import contextlib
import io
import logging
import subprocess
import sys
from pathlib import Path

from bench.cli.main import main

ROOT = Path(__file__).resolve().parents[1]


def wfsbench(*args: str) -> subprocess.CompletedProcess:
    """``wfsbench ARGS`` run by its entry point in this process, from the repository's root (as
    :func:`wfsbench_process`), its output captured; the result reads as a finished process's. The
    process's logging is put back as it was (a run sends the links' warnings to a file meanwhile)."""
    out, err = io.StringIO(), io.StringIO()
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    try:
        with contextlib.chdir(ROOT), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(list(args))
            except SystemExit as exit_:  # argparse: --help, --version, a command line it cannot use
                code = exit_.code if isinstance(exit_.code, int) else 0
    finally:
        root.handlers[:] = handlers
        root.setLevel(level)
    return subprocess.CompletedProcess(["wfsbench", *args], int(code), out.getvalue(), err.getvalue())


def wfsbench_process(*args: str, timeout_s: float = 120) -> subprocess.CompletedProcess:
    """``wfsbench ARGS`` in a process of its own (the installed console script, else the module)."""
    script = Path(sys.executable).with_name("wfsbench")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "bench.cli"]
    return subprocess.run(
        [*command, *args], capture_output=True, text=True, timeout=timeout_s, cwd=ROOT, check=False
    )
