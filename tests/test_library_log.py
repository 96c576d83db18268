"""The links' and libraries' log records (pymodbus's retries with raw frames among them) go to the
log file beside the output while a command runs, never to the terminal; the file is made only when
there is something to write, and the process's logging is as it was afterwards."""

from __future__ import annotations

import logging

from bench.app.library_log import library_log, log_beside

#: What pymodbus writes when a reply does not come: its last frames in hex.
FRAMES = (
    "No response received after 3 retries, continue with next request\n>>>>> send: 0x0 0x1 0x0 0x0 0x0 0x6"
)


def test_a_library_warning_goes_to_the_file_not_to_standard_error(tmp_path, capfd):
    path = log_beside(tmp_path / "campaign.h5")
    assert path.name == "campaign.h5.log"
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    with library_log(path) as log:
        logging.getLogger("pymodbus.logging").warning(FRAMES)
        logging.getLogger("drivers.actuator").info("a detail below the file's level")
    assert log.written
    assert capfd.readouterr().err == ""
    text = path.read_text()
    assert "pymodbus.logging WARNING: No response received after 3 retries" in text
    assert ">>>>> send: 0x0 0x1" in text and "a detail below" not in text
    assert root.handlers == handlers and root.level == level


def test_nothing_to_write_makes_no_file_and_an_earlier_log_is_appended_to(tmp_path):
    path = tmp_path / "campaign.h5.log"
    with library_log(path) as log:
        pass
    assert not log.written and not path.exists()
    path.write_text("an earlier run's warning\n")
    with library_log(path) as log:
        logging.getLogger("drivers.wfs_reader").warning("frames lost: 12")
    assert log.written
    assert path.read_text().splitlines()[0] == "an earlier run's warning"
