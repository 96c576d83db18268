"""The person at the bench, asked at the terminal: prompts read from standard input, checked, and
asked again on a bad answer."""

from __future__ import annotations

from collections.abc import Callable

from sequences import AnswerError, Prompt


def prompt_hint(prompt: Prompt) -> str:
    """What a prompt accepts, for the person answering it."""
    if prompt.answer == "number":
        lo = "" if prompt.minimum is None else f"{prompt.minimum:g}"
        hi = "" if prompt.maximum is None else f"{prompt.maximum:g}"
        unit = f" {prompt.unit}" if prompt.unit else ""
        return f" [{lo}..{hi}{unit}]"
    if prompt.answer == "choice":
        return f" [{' / '.join(prompt.choices)}]"
    return " [yes / no]"


class TerminalOperator:
    """Asks each prompt with ``read`` (``input`` by default) until the answer is valid; the end of
    the input is no answer (:class:`AnswerError`, which aborts the sequence)."""

    def __init__(self, read: Callable[[str], str] = input, write: Callable[[str], None] = print) -> None:
        self.read = read
        self.write = write

    def answer(self, prompt: Prompt) -> object:
        while True:
            try:
                text = self.read(f"{prompt.text}{prompt_hint(prompt)}: ")
            except EOFError:
                raise AnswerError(f"{prompt.id}: no answer, the input ended") from None
            try:
                return prompt.check_answer(text)
            except AnswerError as exc:
                self.write(f"  {exc}; try again")
