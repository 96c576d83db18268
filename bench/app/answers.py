"""Operator answers from a file, for unattended runs (docs/cli.md, "Answers file").

The file is TOML: one key per prompt id of the sequence, its value the answer (a number for a
"number" prompt, ``true``/``false`` for a confirmation, a string for a choice). The whole file is
checked against the sequence's prompts before anything is opened: every prompt needs a valid answer,
and a key that names no prompt is refused too, so a typo cannot leave a prompt unanswered halfway
through a campaign.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path

from bench.app.terminal import prompt_hint
from sequences import AnswerError, Prompt, Sequence
from simulators.world import SimulatedOperator


class AnswersError(ValueError):
    """The answers file does not answer the sequence's prompts; the message names the file, the
    prompt id and what the prompt allows."""


def load_answers(path: Path, sequence: Sequence) -> dict[str, float | str | bool]:
    """Every prompt of ``sequence`` with its checked answer from the TOML file at ``path``."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except OSError as exc:
        raise AnswersError(f"{path}: cannot read the answers file: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise AnswersError(f"{path}: not valid TOML: {exc}") from None
    prompts = {step.id: step for step in sequence.steps if isinstance(step, Prompt)}
    unknown = sorted(set(data) - set(prompts))
    if unknown:
        known = ", ".join(prompts) or "none"
        raise AnswersError(
            f"{path}: {unknown[0]}: no prompt of sequence {sequence.name!r} has this id"
            f" (its prompts: {known})"
        )
    answers: dict[str, float | str | bool] = {}
    for prompt_id, prompt in prompts.items():
        if prompt_id not in data:
            raise AnswersError(
                f"{path}: {prompt_id}: no answer for the prompt {prompt.text!r};"
                f" allowed:{prompt_hint(prompt)}"
            )
        try:
            answers[prompt_id] = prompt.check_answer(data[prompt_id])
        except AnswerError as exc:
            raise AnswersError(f"{path}: {exc}; allowed:{prompt_hint(prompt)}") from None
    return answers


class FileAnswers:
    """The operator of an unattended run: answers each prompt from the checked answers. On the
    simulated bench the answer is applied to the simulated world, as the simulated technician
    (:class:`bench.app.simulated.TargetAnswers`) applies its own."""

    def __init__(
        self, answers: Mapping[str, float | str | bool], world_operator: SimulatedOperator | None = None
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
