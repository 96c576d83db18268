"""The post-run analysis in a process of its own, off the bench's real-time path.

The analysis of a run (a whole grid's tyre identification, the four-post quarter car) is seconds of
numerical work. In the bench's process it would hold the interpreter's lock against the WFS reader,
the heartbeat and the engine's loop while the next run is under way; here it runs in a child
interpreter (:mod:`bench.app.child_process`) holding a :class:`~bench.app.run_analysis.RunAnalyser`.
The bench reads each run's records from its campaign file
(:func:`~bench.app.run_analysis.run_inputs`; the file is the bench's own while it records) and sends
them; the child sends back, for each, the analysis, what it changed in the campaign's knowledge,
the analysis's record and the report's figures the run changed. Both ways the messages are
pickles, one after the other, on the child's standard input and output: first the campaign's
knowledge, then one
:class:`~bench.app.run_analysis.RunInputs` per run with whether to draw its figures (not for a run
analysed again whose figures its campaign kept already); back, for each run in the order they were sent,
its ``RunAnalysis``, what it changed in the campaign's knowledge
(:func:`~bench.app.analysis_record.knowledge_changes`) and the record the campaign file keeps of it
(:func:`~bench.app.analysis_record.record_text`: made here, off the bench's path) and the figures
(:class:`~bench.app.kept_figures.FigureDrawer`: drawn here too), the changes of which
:class:`AnalysisProcess` applies to the knowledge it was given. Only the changes travel: the
whole knowledge grows with every run, and unpickling it after each would hold the interpreter's lock
(and wake its garbage collector) for tens of milliseconds.

A message's arrays travel beside its pickle, not in it (protocol 5's out-of-band buffers): a
grid's records are megabytes, and copying them into one pickle would hold the interpreter's lock for
milliseconds on end; written as they lie, the lock is released while the pipe takes them. Framing:
the pickle's length and the number of buffers (little-endian u64, u32), each buffer's length (u64),
then the pickle and the buffers. The bench never waits on the child to send: a sender thread writes
what :meth:`AnalysisProcess.submit` queued, as the child reads it between analyses.
"""

from __future__ import annotations

import os
import pickle
import queue
import struct
import subprocess
import threading
from typing import IO, NamedTuple

from bench.analysis.campaign import CampaignKnowledge, RunAnalysis
from bench.app.analysis_record import KnowledgeChanges, analyse_and_record, apply_changes
from bench.app.child_process import Child, start_child
from bench.app.kept_figures import DrawnFigures, FigureDrawer
from bench.app.run_analysis import RunAnalyser, RunInputs


class AnalysisReply(NamedTuple):
    """What the child sends back for each run: its analysis, the changes it made to the campaign's
    knowledge, its record's text, the figures the run changed and why any of those could not be
    drawn (:class:`~bench.app.kept_figures.DrawnFigures`)."""

    outcome: RunAnalysis
    changes: KnowledgeChanges
    record: str
    figures: DrawnFigures

#: How long closing waits for the child to end once its input is closed (s).
STOP_TIMEOUT_S = 10.0

#: The analysis process's scheduling policy (Linux): batch, at the bench's priority. It is background
#: work, so a thread of the bench that wakes (the WFS reader, the heartbeat) comes first; but the
#: bench waits for some of its results (a free run's plate mass, before a run that needs it), so it
#: is not given a lower priority: behind four busy processes a nice of 10 left it about 1 % of a core,
#: and loading its libraries alone took over a minute while the sequence waited for it.
SCHEDULING_POLICY = getattr(os, "SCHED_BATCH", None)


class AnalysisProcessError(RuntimeError):
    """The analysis process ended before it answered every run sent to it."""


class AnalysisProcess:
    """A :class:`~bench.app.run_analysis.RunAnalyser` in a child process: :meth:`submit` sends a run,
    :meth:`next_result` takes the analyses back in order. Use as a context manager."""

    def __init__(self, knowledge: CampaignKnowledge) -> None:
        self.knowledge = knowledge
        self._process: Child | None = None
        self._outbox: queue.Queue[object] = queue.Queue()  # to the child; _END closes its input
        self._results: queue.Queue[AnalysisReply | BaseException] = queue.Queue()
        self._threads: list[threading.Thread] = []
        self.outstanding = 0  # runs sent and not yet taken back

    def __enter__(self) -> AnalysisProcess:
        process = self._process = start_child("bench.app.analysis_process", text=False)
        self._threads = [
            threading.Thread(target=work, args=(process,), name=f"analysis-{name}", daemon=True)
            for work, name in ((self._send_all, "sender"), (self._receive, "results"))
        ]
        for thread in self._threads:
            thread.start()
        self._outbox.put(self.knowledge)
        return self

    def __exit__(self, *exc: object) -> None:
        """Close the child's input (it ends after the run it is analysing) and wait for it; a child
        that does not end is killed."""
        process, self._process = self._process, None
        if process is None:
            return
        self._outbox.put(_END)
        try:
            process.wait(STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        for thread in self._threads:
            thread.join(STOP_TIMEOUT_S)

    def submit(self, run: RunInputs, *, draw: bool = True) -> None:
        """Queue ``run`` to be analysed after those sent before it. It never waits for the child: a
        sender thread writes to its input, which it reads between analyses."""
        if self._process is None:
            raise AnalysisProcessError("the analysis process is not running")
        self._outbox.put((run, draw))
        self.outstanding += 1

    def next_result(self, timeout_s: float | None) -> AnalysisReply | None:
        """The next analysis, its record's text (:mod:`bench.app.analysis_record`) and the figures it
        changed (:mod:`bench.app.kept_figures`), its changes applied to :attr:`knowledge`, waiting up
        to ``timeout_s`` (None: until it comes; 0: only if it is there); None if none came.
        AnalysisProcessError if the child ended before answering."""
        if self.outstanding == 0:
            return None
        try:
            result = self._results.get(timeout=timeout_s) if timeout_s != 0 else self._results.get_nowait()
        except queue.Empty:
            return None
        if isinstance(result, BaseException):
            self._results.put(result)  # every later call fails alike
            raise AnalysisProcessError(f"the analysis process ended: {result}")
        self.outstanding -= 1
        apply_changes(self.knowledge, result.changes)
        return result

    def _send_all(self, process: Child) -> None:
        """The sender thread: everything queued, in order, until _END closes the child's input. A
        child that is gone ends it; the receiver then reports the child's end."""
        assert process.stdin is not None
        try:
            while (message := self._outbox.get()) is not _END:
                write_message(process.stdin, message)
            process.stdin.close()
        except OSError:
            pass  # the child is gone: the receiver's end of file says so to whoever waits

    def _receive(self, process: Child) -> None:
        assert process.stdout is not None
        try:
            while True:
                self._results.put(read_message(process.stdout))
        except EOFError:
            self._results.put(EOFError("no more results"))
        except Exception as exc:  # a broken pipe or a garbled pickle: every waiting call is told
            self._results.put(exc)


#: Put in the sender's queue to close the child's input.
_END = object()
_HEAD = struct.Struct("<QI")
_LENGTH = struct.Struct("<Q")
#: Bounds beyond which a frame's header is garbage, not a campaign's records (whose arrays are each a
#: channel's samples of one point).
_MAX_BUFFERS = 1 << 24
_MAX_BYTES = 1 << 32


def write_message(stream: IO[bytes], message: object) -> None:
    """Write ``message`` as one frame (the module's docstring): its arrays as they lie in memory."""
    buffers: list[pickle.PickleBuffer] = []
    payload = pickle.dumps(message, protocol=5, buffer_callback=buffers.append)
    views = [buffer.raw() for buffer in buffers]
    stream.write(_HEAD.pack(len(payload), len(views)) + b"".join(_LENGTH.pack(v.nbytes) for v in views))
    stream.write(payload)
    for view in views:
        stream.write(view)
    stream.flush()


def read_message(stream: IO[bytes]) -> object:
    """Read one frame written by :func:`write_message`; EOFError at the end of the stream, before or
    inside a frame."""
    length, count = _HEAD.unpack(_read_exactly(stream, _HEAD.size))
    if count > _MAX_BUFFERS:
        raise pickle.UnpicklingError(f"a frame of {count} buffers: not a message of this protocol")
    lengths = _read_exactly(stream, count * _LENGTH.size)
    sizes = [_LENGTH.unpack_from(lengths, i * _LENGTH.size)[0] for i in range(count)]
    if (largest := max([length, *sizes])) > _MAX_BYTES:
        raise pickle.UnpicklingError(f"a frame part of {largest} bytes: not a message of this protocol")
    payload = _read_exactly(stream, length)
    return pickle.loads(payload, buffers=[_read_exactly(stream, size) for size in sizes])


def _read_exactly(stream: IO[bytes], size: int) -> bytearray:
    """``size`` bytes (a writable buffer: arrays built on it are writable, as the analysis's own)."""
    buffer = bytearray(size)
    view, got = memoryview(buffer), 0
    while got < size:
        n = stream.readinto(view[got:])
        if not n:
            raise EOFError(f"the stream ended {size - got} bytes short of a message")
        got += n
    return buffer


def _serve(stdin: IO[bytes], stdout: IO[bytes]) -> None:
    """The child's side: the knowledge, then one analysis per run until its input closes. An
    analysis that fails in a way the analyser does not flag itself is sent back flagged too."""
    analyser = RunAnalyser(read_message(stdin))
    drawer = _figure_drawer(analyser.knowledge)
    while True:
        try:
            run, draw = read_message(stdin)
        except EOFError:
            return
        outcome, changes, record = analyse_and_record(analyser, run, flag_defects=True)
        write_message(stdout, AnalysisReply(outcome, changes, record, _figures(drawer, run, analyser, draw)))


def _figure_drawer(knowledge: CampaignKnowledge) -> FigureDrawer | str:
    """The process's figure drawer, or why there is none (a kept figure only spares the report its
    drawing: a failure here is said, never the process's end)."""
    try:
        return FigureDrawer(knowledge)
    except Exception as exc:  # any defect of the figures' code, whatever it raises
        return f"figures not drawn by the analysis process: {type(exc).__name__}: {exc}"


def _figures(drawer: FigureDrawer | str, run: RunInputs, analyser: RunAnalyser, draw: bool) -> DrawnFigures:
    """The figures ``run``'s analysis changed (:meth:`FigureDrawer.after`), or why none were drawn."""
    if isinstance(drawer, str):
        return DrawnFigures(failed=(drawer,))
    try:
        return drawer.after(run, analyser.knowledge, draw=draw)
    except Exception as exc:  # a defect of the figures' code (each figure's own failure is caught there)
        return DrawnFigures(failed=(f"figures not drawn: {type(exc).__name__}: {exc}",))


def child_main(stdin: IO[bytes], stdout: IO[bytes]) -> None:
    """The child's side (:mod:`bench.app.child_process`): background work, then the protocol."""
    if SCHEDULING_POLICY is not None:
        os.sched_setscheduler(0, SCHEDULING_POLICY, os.sched_param(0))
    _serve(stdin, stdout)
