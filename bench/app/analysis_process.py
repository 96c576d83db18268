"""The post-run analysis in a process of its own, off the bench's real-time path.

The analysis of a run (a whole grid's tyre identification, the four-post quarter car) is seconds of
numerical work. In the bench's process it would hold the interpreter's lock against the WFS reader,
the heartbeat and the engine's loop while the next run is under way; here it runs in a child
interpreter (:mod:`bench.app.child_process`) holding a :class:`~bench.app.run_analysis.RunAnalyser`.
The bench reads each run's records from its campaign file (:func:`~bench.app.run_analysis.run_inputs`;
the file is the bench's own while it records) and sends them; the child sends back, for each, the
analysis and what the campaign knows after it. Both ways the messages are pickles, one after the
other, on the child's standard input and output: first the campaign's knowledge, then one
:class:`~bench.app.run_analysis.RunInputs` per run; back one ``(RunAnalysis, CampaignKnowledge)`` per
run, in the order they were sent.
"""

from __future__ import annotations

import pickle
import queue
import subprocess
import sys
import threading
from typing import IO

from bench.analysis.campaign import CampaignKnowledge, RunAnalysis
from bench.app.child_process import start_child
from bench.app.run_analysis import RunAnalyser, RunInputs

#: How long closing waits for the child to end once its input is closed (s).
STOP_TIMEOUT_S = 10.0


class AnalysisProcessError(RuntimeError):
    """The analysis process ended before it answered every run sent to it."""


class AnalysisProcess:
    """A :class:`~bench.app.run_analysis.RunAnalyser` in a child process: :meth:`submit` sends a run,
    :meth:`next_result` takes the analyses back in order. Use as a context manager."""

    def __init__(self, knowledge: CampaignKnowledge) -> None:
        self.knowledge = knowledge
        self._process: subprocess.Popen[bytes] | None = None
        self._results: queue.Queue[tuple[RunAnalysis, CampaignKnowledge] | BaseException] = queue.Queue()
        self._receiver: threading.Thread | None = None
        self.outstanding = 0  # runs sent and not yet taken back

    def __enter__(self) -> AnalysisProcess:
        self._process = start_child("bench.app.analysis_process", text=False)
        self._receiver = threading.Thread(target=self._receive, name="analysis-results", daemon=True)
        self._receiver.start()
        self._send(self.knowledge)
        return self

    def __exit__(self, *exc: object) -> None:
        """Close the child's input (it ends after the run it is analysing) and wait for it; a child
        that does not end is killed."""
        process, self._process = self._process, None
        if process is None:
            return
        try:
            assert process.stdin is not None
            process.stdin.close()
            process.wait(STOP_TIMEOUT_S)
        except (OSError, subprocess.TimeoutExpired):
            process.kill()
            process.wait()

    def submit(self, run: RunInputs) -> None:
        """Send ``run`` to be analysed after those sent before it."""
        self._send(run)
        self.outstanding += 1

    def next_result(self, timeout_s: float | None) -> tuple[RunAnalysis, CampaignKnowledge] | None:
        """The next analysis and the knowledge after it, waiting up to ``timeout_s`` (None: until it
        comes; 0: only if it is there); None if none came. AnalysisProcessError if the child ended
        before answering."""
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
        return result

    def _send(self, message: object) -> None:
        process = self._process
        if process is None or process.stdin is None:
            raise AnalysisProcessError("the analysis process is not running")
        try:
            pickle.dump(message, process.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            process.stdin.flush()
        except OSError as err:
            raise AnalysisProcessError(f"the analysis process is gone: {err}") from None

    def _receive(self) -> None:
        process = self._process
        assert process is not None and process.stdout is not None
        try:
            while True:
                self._results.put(pickle.load(process.stdout))
        except EOFError:
            self._results.put(EOFError("no more results"))
        except Exception as exc:  # a broken pipe or a garbled pickle: every waiting call is told
            self._results.put(exc)


def _serve(stdin: IO[bytes], stdout: IO[bytes]) -> None:
    """The child's side: the knowledge, then one analysis per run until its input closes. An
    analysis that fails in a way the analyser does not flag itself is sent back flagged too."""
    analyser = RunAnalyser(pickle.load(stdin))
    while True:
        try:
            run: RunInputs = pickle.load(stdin)
        except EOFError:
            return
        try:
            outcome = analyser.analyse(run)
        except Exception as exc:
            outcome = RunAnalysis.failed(run.run_id, run.kind, f"{type(exc).__name__}: {exc}")
            analyser.knowledge.analysed_runs[run.run_id] = outcome
        pickle.dump((outcome, analyser.knowledge), stdout, protocol=pickle.HIGHEST_PROTOCOL)
        stdout.flush()


if __name__ == "__main__":
    protocol_in, protocol_out = sys.stdin.buffer, sys.stdout.buffer
    sys.stdout = sys.stderr  # a stray print cannot corrupt the protocol
    _serve(protocol_in, protocol_out)
