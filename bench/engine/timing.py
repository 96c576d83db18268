"""The engine's timeouts and periods, each a key of the bench configuration's ``[timing]`` table
(docs/configuration.md) with the default given here.

Every bound is wall time (s) unless it says samples: the WFS sample counter is the clock of the
acquisition, the wall clock serves timeouts and watchdogs only.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class EngineTiming:
    """Bounds (s): how long to wait for a block of frames, how often to read the controller's status
    during an excitation, how long after START the excitation must show on the sync bits (wall
    time and samples, whichever is later: frames recorded before the START took effect may still
    be queued), the margin (s of samples) beyond its planned duration after which a started
    excitation counts as hung (samples received or reported lost count alike), and how long a
    triggered capture may take to arrive after the blow was asked for (beyond its own length), and
    how long a reset may take (the controller tapers out of an e-stop before it takes commands).

    ``backlog_s`` (s of samples): how far the acquisition may run ahead of the engine before the
    reader waits for it. A real acquisition cannot wait (its frames overflow once the serial port's
    buffer is full), so the default covers the longest stall of the engine; a simulated one that
    waits for its host needs little, and a short backlog keeps it from simulating rest the engine
    records while it is busy between points.

    ``wfs_silence_s``: how long no byte may arrive at the WFS port while it should stream before the
    run is stopped as "WFS link lost" (judged at the port: bytes waiting there unread are the host's
    delay, not the link's); ``host_stall_s``: a port left unread this long by the host (a busy
    machine) is recorded as a host stall, and stops the run only when frames were lost to it (a
    real tty's 4095-byte buffer lasts 44 ms at 921600 baud: a longer stall can lose frames);
    ``connect_timeout_s``: how long opening the bench waits for
    the WFS port to open."""

    block_timeout_s: float = 0.05
    status_period_s: float = 0.2
    start_timeout_s: float = 5.0
    end_margin_s: float = 5.0
    capture_timeout_s: float = 10.0
    reset_timeout_s: float = 10.0
    backlog_s: float = 2.0
    wfs_silence_s: float = 0.5
    host_stall_s: float = 0.05
    connect_timeout_s: float = 5.0
