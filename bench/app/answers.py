"""Operator answers from a file, for unattended runs (docs/cli.md, "Answers file").

The file is TOML: one key per prompt id of the sequence, its value the answer (a number for a
"number" prompt, ``true`` for a confirmation, a string for a choice). The whole file is checked
against the sequence's prompts before anything is opened: every prompt needs a valid answer, and a
key that names no prompt is refused too, so a typo cannot leave a prompt unanswered halfway through
a campaign; a "no" to a confirmation is refused as well, since the sequence would abort there.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Protocol

from bench.app.terminal import prompt_hint
from sequences import AnswerError, Prompt, Sequence
from sequences.errors import problems_text
from sequences.toml_text import load_toml, toml_error_where, toml_value


class WorldOperator(Protocol):
    """The operator's hands on a simulated world (:class:`simulators.world.SimulatedOperator`, or
    one in the simulated lab's own process): does what a prompt's action asks, with the answer."""

    def apply(self, action: str, answer: float | str | bool | None) -> None: ...


class AnswersError(ValueError):
    """The answers file does not answer the sequence's prompts: ``problems`` lists every
    ``file: prompt id: reason`` found (with what the prompt allows), one line each in the message, as
    a sequence file's error does."""

    def __init__(self, problems: list[str]) -> None:
        self.problems = tuple(problems)
        super().__init__(problems_text(problems))


def load_answers(path: Path, sequence: Sequence) -> dict[str, float | str | bool]:
    """Every prompt of ``sequence`` with its checked answer from the TOML file at ``path``.

    :class:`AnswersError` lists every problem: the file's keys in its order (a key that names no
    prompt, an answer the prompt refuses, a "no" to a confirmation, which would abort the sequence
    at that prompt), then the prompts the file does not answer, in the sequence's order."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
        data = load_toml(text)
    except OSError as exc:
        raise AnswersError([f"{path}: cannot read the answers file: {exc.strerror or exc}"]) from None
    except UnicodeDecodeError as exc:
        raise AnswersError([f"{path}: not UTF-8 text: {exc.reason} at byte {exc.start}"]) from None
    except tomllib.TOMLDecodeError as exc:
        key, reason = toml_error_where(text, str(exc))
        raise AnswersError([f"{path}: {key + ': ' if key else ''}{reason}"]) from None
    prompts = {step.id: step for step in sequence.steps if isinstance(step, Prompt)}
    answers: dict[str, float | str | bool] = {}
    problems = []
    for prompt_id, value in data.items():
        prompt = prompts.get(prompt_id)
        if prompt is None:
            known = ", ".join(prompts) or "none"
            problems.append(
                f"{path}: {prompt_id}: no prompt of sequence {sequence.name!r} has this id"
                f" (its prompts: {known})"
            )
            continue
        try:
            answers[prompt_id] = prompt.check_answer(_typed(prompt, value))
        except AnswerError as exc:
            problems.append(f"{path}: {exc}; allowed:{prompt_hint(prompt)}")
            continue
        if prompt.answer == "confirm" and answers[prompt_id] is False:
            problems.append(
                f"{path}: {prompt_id}: answered no to the confirmation {prompt.text!r}: the sequence"
                " would abort there; an unattended run needs yes"
            )
    problems += [
        f"{path}: {prompt_id}: no answer for the prompt {prompt.text!r}; allowed:{prompt_hint(prompt)}"
        for prompt_id, prompt in prompts.items()
        if prompt_id not in data
    ]
    if problems:
        raise AnswersError(problems)
    return answers


#: The words a confirmation takes in an answers file besides ``true`` and ``false``, in any case.
FILE_CONFIRM_WORDS = ("yes", "no")


def _typed(prompt: Prompt, value: object) -> object:
    """``value`` if its TOML type is the one the prompt's answer takes in a file (a number for a
    number, a boolean or "yes" / "no" for a confirmation, a string for a choice), else
    :class:`AnswerError` saying which type: a file states its answers, it is not typed text (the
    terminal's "2.4" or "y"), and a sequence file refuses a string where a number belongs too."""
    shown = toml_value(value) if isinstance(value, bool | int | float | str) else repr(value)
    if prompt.answer == "number" and (isinstance(value, bool) or not isinstance(value, int | float)):
        unquote = " (write the number without quotes)" if isinstance(value, str) else ""
        raise AnswerError(f"{prompt.id}: {shown} is {_toml_type(value)}, not a number{unquote}")
    if prompt.answer == "confirm" and not (
        isinstance(value, bool) or (isinstance(value, str) and value.strip().lower() in FILE_CONFIRM_WORDS)
    ):
        raise AnswerError(f'{prompt.id}: {shown} is not a confirmation: true or false (or "yes" / "no")')
    if prompt.answer == "choice" and not isinstance(value, str):
        raise AnswerError(f"{prompt.id}: {shown} is {_toml_type(value)}, not one of the choices (a string)")
    return value


def _toml_type(value: object) -> str:
    for kind, name in ((bool, "a boolean"), (str, "a string"), (int, "an integer"), (float, "a float")):
        if isinstance(value, kind):
            return name
    return (
        "an array" if isinstance(value, list) else "a table" if isinstance(value, dict) else "a date or time"
    )


class FileAnswers:
    """The operator of an unattended run: answers each prompt from the checked answers. On the
    simulated bench the answer is applied to the simulated world, as the simulated technician
    (:class:`bench.app.simulated.TargetAnswers`) applies its own."""

    def __init__(
        self, answers: Mapping[str, float | str | bool], world_operator: WorldOperator | None = None
    ) -> None:
        self.answers = answers
        self.world_operator = world_operator

    def answer(self, prompt: Prompt) -> object:
        if prompt.id not in self.answers:
            raise AnswerError(f"{prompt.id}: no answer in the answers file")
        value = prompt.check_answer(self.answers[prompt.id])
        if self.world_operator is not None and prompt.action is not None:
            self.world_operator.apply(prompt.action, value)
        return value
