"""Modal dialogs: a sequence's prompt, a confirmation before the bench moves, the operator and
notes recorded with the runs to come, the help text."""

from __future__ import annotations

from typing import ClassVar

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical, VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Input, Label, Static

from bench.app.terminal import prompt_hint
from sequences import AnswerError, Prompt
from sequences.metadata import LABELS

#: Shown in every dialog: the e-stop key works there too.
ESTOP_HINT = "[b white on red] F12 E-STOP [/]"
#: Shown under a prompt's text field, where p, r and a are typed: what acts on the sequence.
FIELD_KEYS = "F6 pause    F7 resume    F8 abort    Escape: no answer (aborts)"


class PromptDialog(ModalScreen[object]):
    """A prompt of the sequence. A number or a choice is typed and checked (a bad answer is shown
    and asked again); a confirmation is answered yes or no. Dismissed with the valid answer; Escape
    dismisses with an :class:`AnswerError` (no answer: the engine aborts the sequence)."""

    BINDINGS: ClassVar[list[Binding]] = [
        Binding("y", "confirm(True)", "Yes"),
        Binding("n", "confirm(False)", "No"),
        Binding("escape", "no_answer", "No answer (abort)"),
    ]

    def __init__(self, prompt: Prompt) -> None:
        super().__init__(id="prompt-dialog")
        self.prompt = prompt
        self.closed = False  # answered, or closed unanswered: it closes once

    def answer(self, value: object) -> None:
        if not self.closed:
            self.closed = True
            self.dismiss(value)

    def close_unanswered(self) -> None:
        """The sequence ended while the dialog was open (an abort): close it, answering nothing."""
        if not self.closed:
            self.closed = True
            self.app.pop_screen()

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Label(ESTOP_HINT)
            yield Static(f"[b]{self.prompt.text}[/b]", id="prompt-text")
            if self.prompt.answer == "confirm":
                yield Label("y: done / confirmed    n: decline (aborts the sequence)", id="prompt-keys")
                yield Label("p pause    r resume    a abort", id="prompt-run-keys")
            else:
                yield Label(f"answer{prompt_hint(self.prompt)}, then Enter", id="prompt-keys")
                yield Input(placeholder=prompt_hint(self.prompt).strip(), id="prompt-input")
                # p, r and a go into the field: the function keys act on the sequence from here
                yield Label(FIELD_KEYS, id="prompt-run-keys")
            error = Static("", id="prompt-error")
            error.display = False  # until an answer is refused
            yield error

    def on_mount(self) -> None:
        if self.prompt.answer != "confirm":
            self.query_one("#prompt-input", Input).focus()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        return action != "confirm" or self.prompt.answer == "confirm"

    def action_confirm(self, yes: bool) -> None:
        self.answer(yes)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        try:
            value = self.prompt.check_answer(event.value)
        except AnswerError as exc:
            error = self.query_one("#prompt-error", Static)
            error.update(f"[red]{exc}: try again[/red] (p, r, a type here: F6 pauses, F8 aborts)")
            error.display = True
            event.input.value = ""
            return
        self.answer(value)

    def action_no_answer(self) -> None:
        self.answer(AnswerError(f"{self.prompt.id}: no answer, the technician cancelled"))


class ConfirmDialog(ModalScreen[bool]):
    """Asks before a command that moves or changes the bench: y confirms, n or Escape does not."""

    BINDINGS: ClassVar[list[Binding]] = [
        Binding("y", "answer(True)", "Yes"),
        Binding("n", "answer(False)", "No"),
        Binding("escape", "answer(False)", "No", show=False),
    ]

    def __init__(self, question: str) -> None:
        super().__init__(id="confirm-dialog")
        self.question = question

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Label(ESTOP_HINT)
            yield Static(f"[b]{self.question}[/b]", id="confirm-question")
            yield Label("y: yes    n: no")

    def action_answer(self, yes: bool) -> None:
        self.dismiss(yes)


class MetadataDialog(ModalScreen[dict[str, str] | None]):
    """The operator and notes recorded with the runs the next sequences begin (docs/tui.md). Two
    text fields filled with what is set now; Tab moves between them, Enter in either keeps both,
    Escape keeps what was set before. Dismissed with the fields (an empty one: not given), or None."""

    FIELDS = ("operator", "notes")
    BINDINGS: ClassVar[list[Binding]] = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, current: dict[str, str]) -> None:
        super().__init__(id="metadata-dialog")
        self.current = current

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Label(ESTOP_HINT)
            yield Static("[b]Operator and notes[/b], recorded with every run the next sequences begin")
            for name in self.FIELDS:
                yield Label(f"{LABELS[name]}:")
                yield Input(
                    self.current.get(name, ""),
                    placeholder=f"{LABELS[name]} (empty: not given)",
                    id=f"meta-{name}",
                )
            yield Label("Tab: next field    Enter: keep    Escape: cancel", id="metadata-keys")

    def on_mount(self) -> None:
        self.query_one(f"#meta-{self.FIELDS[0]}", Input).focus()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self.dismiss({name: self.query_one(f"#meta-{name}", Input).value.strip() for name in self.FIELDS})

    def action_cancel(self) -> None:
        self.dismiss(None)


HELP_TEXT = """\
[b]Keys[/b] (also in the footer of each screen)

  [b red]F12[/b red]   E-STOP: stops the actuator at once, from every screen and dialog
  F2    Bench: links, hydraulics, interlocks, live values, counters
  F3    Sequence: pick and check a sequence file, start it
  F4    Run: progress, current step, live plots, amplitudes
  F5    Results: the analysis, Bode plot, valid bands, past runs
  ?     this help          q   quit (not while a sequence runs)

[b]Bench[/b]     l / h / o: hydraulics low / high / off    t: tare
          x: reset an interlock or e-stop
          (each asks for a confirmation: y / n)
[b]Sequence[/b]  Enter on a shipped sequence, or type a file's path and Enter:
          checked and dry-run; g starts it once it is valid
          (a file holding runs of it already: g offers to resume them)
          m: the operator and notes recorded with its runs
[b]Run[/b]       p pause   r resume   a abort   (F6 / F7 / F8 as well)
[b]Prompts[/b]   a number: type it and Enter (a bad value is asked again);
          a confirmation: y or n;
          Escape gives no answer and aborts the sequence;
          in a text field p, r, a are typed: F6 / F7 / F8 act

A link loss or an interlock shows as a red banner with its reason;
x on the Bench screen resets once the cause is cleared.
"""


class HelpDialog(ModalScreen[None]):
    """The keys. Each line of the text fits the dialog as it is (no line is broken by the
    dialog's width, which would split a key from what it does)."""

    BINDINGS: ClassVar[list[Binding]] = [Binding("escape,question_mark,q", "close", "Close")]

    def compose(self) -> ComposeResult:
        with VerticalScroll(classes="dialog", id="help"):  # scrolls with the arrows where it is cut
            yield Label(ESTOP_HINT)
            yield Static(HELP_TEXT, id="help-text")
            yield Label("Escape closes")

    def on_mount(self) -> None:
        self.query_one("#help", VerticalScroll).focus()

    def action_close(self) -> None:
        self.dismiss(None)
