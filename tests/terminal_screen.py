"""What a terminal shows of the text a command wrote, control codes and all: a small model of a
screen, enough to test what a live display leaves on it and where, without a terminal emulator.

It knows what a one-line live display writes: text, carriage return, newline (a terminal's output
processing makes it a carriage return too), cursor up, erase in line, the cursor shown or hidden,
and colours (ignored). Any other control sequence fails the test that met it, so that a display
writing something this model cannot follow is noticed rather than misread. Lines have no width: a
line written past the terminal's edge shows as one long line (what a test of the width checks).
"""

from __future__ import annotations

import re

#: A control sequence (CSI: ESC [, parameters, final letter), a carriage return, a newline, or text.
TOKEN = re.compile(r"\x1b\[([?0-9;]*)([A-Za-z])|(\r)|(\n)|([^\x1b\r\n]+)|(\x1b)")


class Screen:
    """The lines on the screen (scrollback included), the cursor's row and column, whether the
    cursor is shown, and every line erased as it was (what a live display drew, redraw by redraw)."""

    def __init__(self) -> None:
        self.lines = [""]
        self.erased: list[str] = []
        self.row = self.column = 0
        self.cursor_shown = True

    def feed(self, text: str) -> Screen:
        """``text`` written at the cursor; returns the screen."""
        for match in TOKEN.finditer(text):
            parameters, final, carriage_return, newline, plain, lone_escape = match.groups()
            if final is not None:
                self._control(parameters, final)
            elif carriage_return:
                self.column = 0
            elif newline:
                self.row, self.column = self.row + 1, 0
                if self.row == len(self.lines):
                    self.lines.append("")
            elif plain is not None:
                line = self.lines[self.row].ljust(self.column)
                self.lines[self.row] = line[: self.column] + plain + line[self.column + len(plain) :]
                self.column += len(plain)
            else:
                raise AssertionError(f"an escape this screen does not know: {lone_escape!r}")
        return self

    def _control(self, parameters: str, final: str) -> None:
        if final == "m":  # colours and styles
            return
        if final == "A":  # cursor up
            self.row = max(0, self.row - int(parameters or 1))
        elif final == "K" and parameters in ("", "0", "2"):  # erase to the line's end, the whole line
            if self.lines[self.row].strip():
                self.erased.append(self.lines[self.row].rstrip())
            self.lines[self.row] = self.lines[self.row][: self.column] if parameters != "2" else ""
        elif final in "hl" and parameters == "?25":  # the cursor shown, hidden
            self.cursor_shown = final == "h"
        else:
            raise AssertionError(f"a control sequence this screen does not know: ESC [{parameters}{final}")

    @property
    def shown(self) -> list[str]:
        """The lines on the screen, trailing blanks removed, without the empty lines at its end."""
        lines = [line.rstrip() for line in self.lines]
        while lines and not lines[-1]:
            lines.pop()
        return lines

    @property
    def current(self) -> str:
        """The line the cursor is on, trailing blanks removed."""
        return self.lines[self.row].rstrip()
