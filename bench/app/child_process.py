"""Starting one of the bench's own modules as a child process (the simulated lab, the analysis).

The children are forked from a server process that has imported their modules once (Python's
``forkserver``, started at the first child and kept for the bench's life): loading numpy, SciPy and
h5py takes over a second of processor time, which every child would pay again if it started a fresh
interpreter, and a bench starts one per sequence (the analysis) or two (a paced simulated lab).
The server is a clean single-threaded process, so a fork of it is as safe as a fresh interpreter.

A child talks to the bench over two pipes, its input and its output (``stdin`` / ``stdout`` of
:class:`Child`, as a subprocess's), runs in a session of its own (Ctrl-C at the terminal reaches the
bench, which then ends the child in order), and writes nothing to a terminal: its standard output
and error go to ``/dev/null`` (it reports on its output pipe). A child ends when its input closes,
which happens too when the bench process dies, however it dies.

A child module provides ``child_main(stdin, stdout)``: it serves the protocol on the two streams.
"""

from __future__ import annotations

import contextlib
import importlib
import multiprocessing
import os
import subprocess
from multiprocessing.connection import Connection
from typing import IO, Any

#: The modules a child runs; those of every bench are imported once by the server the children are
#: forked from; the web monitor's (``--monitor`` only) in its child, so that a bench without a
#: monitor pays nothing for it.
PRELOADED_CHILDREN = ("bench.app.analysis_process", "bench.app.lab_process")
CHILD_MODULES = (*PRELOADED_CHILDREN, "bench.monitor.server_process")
#: The libraries the analysis imports where it first fits (so that a command that only reads a stored
#: analysis never loads them), imported once by the server too.
FITTING_LIBRARIES = ("scipy.optimize", "scipy.signal", "scipy.stats")

_context = multiprocessing.get_context("forkserver")
_context.set_forkserver_preload([*PRELOADED_CHILDREN, *FITTING_LIBRARIES])


class Child:
    """A started child: its ``pid``, its input and output streams, and the subprocess-like
    :meth:`wait`, :meth:`poll` and :meth:`kill`."""

    def __init__(self, process: multiprocessing.process.BaseProcess, stdin: IO[Any], stdout: IO[Any]) -> None:
        self._process = process
        self.stdin, self.stdout = stdin, stdout

    @property
    def pid(self) -> int:
        assert self._process.pid is not None
        return self._process.pid

    def poll(self) -> int | None:
        return self._process.exitcode

    def wait(self, timeout: float | None = None) -> int:
        """Its exit code once it ended; :class:`subprocess.TimeoutExpired` if it has not within
        ``timeout`` seconds."""
        self._process.join(timeout)
        if self._process.exitcode is None:
            raise subprocess.TimeoutExpired(f"child {self.pid}", timeout or 0.0)
        return self._process.exitcode

    def kill(self) -> None:
        if self._process.exitcode is None:
            self._process.kill()


def start_child(module: str, *, text: bool) -> Child:
    """Start ``module``'s ``child_main`` in a child (see the module's docstring); ``text``:
    line-buffered text streams, else binary ones."""
    if module not in CHILD_MODULES:
        raise ValueError(f"{module} is not one of the children {CHILD_MODULES}")
    child_in, bench_out = _context.Pipe(duplex=False)  # the bench writes, the child reads
    bench_in, child_out = _context.Pipe(duplex=False)  # the child writes, the bench reads
    process = _context.Process(
        target=_child, args=(module, child_in, child_out, text), name=module, daemon=True
    )
    # the first start starts the server (and multiprocessing's resource tracker), which take the
    # standard error they are given: none (a terminal UI's stand-in for it has no descriptor)
    with open(os.devnull, "w") as quiet, contextlib.redirect_stderr(quiet):
        process.start()
    child_in.close()  # the child's ends are the child's: its end of file is the bench's close
    child_out.close()
    return Child(process, _stream(bench_out, "w", text), _stream(bench_in, "r", text))


def _stream(connection: Connection, mode: str, text: bool) -> IO[Any]:
    """A file object on the pipe under ``connection`` (which gives its descriptor up)."""
    fd = os.dup(connection.fileno())
    connection.close()
    if text:
        return os.fdopen(fd, mode, buffering=1, encoding="utf-8")
    return os.fdopen(fd, mode + "b")


def _child(module: str, stdin: Connection, stdout: Connection, text: bool) -> None:
    """In the child: a session of its own, no terminal output, then the module's protocol."""
    os.setsid()
    devnull = os.open(os.devnull, os.O_RDWR)
    for fd in (0, 1, 2):
        os.dup2(devnull, fd)
    os.close(devnull)
    importlib.import_module(module).child_main(_stream(stdin, "r", text), _stream(stdout, "w", text))
