"""The unpaced simulated bench's devices share the bench's process and write only as fast as the
engine drains them: their link falls silent whenever that process waits for the processor, so a
silence shorter than UNPACED_WFS_SILENCE_S is not taken as a lost link there (a busy PC had ended a
terminal UI's smoke run `WFS link lost: no WFS frame for 0.66 s`). A paced bench, as hardware, keeps
the configured limit."""

from __future__ import annotations

import dataclasses

from bench.app.devices import open_bench
from bench.app.engine_build import build_engine
from bench.app.simulated import UNPACED_WFS_SILENCE_S
from bench.config import default_bench_config


def _silence_limit_s(paced: bool, configured_s: float) -> float:
    config = default_bench_config()
    config = dataclasses.replace(
        config,
        simulation=dataclasses.replace(config.simulation, paced=paced),
        timing=dataclasses.replace(config.timing, wfs_silence_s=configured_s),
    )
    with open_bench(config) as devices:
        return build_engine(config, devices).timing.wfs_silence_s


def test_the_unpaced_bench_takes_a_longer_silence_for_a_lost_link_and_the_paced_one_the_configured():
    assert _silence_limit_s(False, 0.5) == UNPACED_WFS_SILENCE_S == 5.0
    assert _silence_limit_s(False, 8.0) == 8.0  # a longer configured limit stands
    assert _silence_limit_s(True, 0.5) == 0.5
