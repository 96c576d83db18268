"""Prompts asked at the terminal: garbage is refused with what is allowed and asked again."""

from __future__ import annotations

import pytest

from bench.app.terminal import TerminalOperator
from sequences import AnswerError, Prompt

PRESSURE = Prompt("p", "Set 2.5 bar", answer="number", unit="bar", minimum=0.5, maximum=4.5, target=2.5)
DAMPER = Prompt("d", "Set the dampers", answer="choice", choices=("soft", "medium", "firm"))
WHEEL = Prompt("w", "Remove the wheel")


def ask(prompt: Prompt, *typed: str) -> tuple[object, list[str], list[str]]:
    typed_left, asked, said = list(typed), [], []

    def read(text: str) -> str:
        asked.append(text)
        if not typed_left:
            raise EOFError
        return typed_left.pop(0)

    return TerminalOperator(read, said.append).answer(prompt), asked, said


def test_a_number_is_asked_again_until_it_is_one_within_the_range():
    answer, asked, said = ask(PRESSURE, "two and a half", "9", "nan", "\x1b[A", " 2.4 ")
    assert answer == 2.4
    assert asked[0] == "Set 2.5 bar [0.5..4.5 bar]: " and len(asked) == 5
    assert all("within 0.5..4.5 bar" in line for line in said) and len(said) == 4


def test_choices_and_confirmations():
    assert ask(DAMPER, "Medium", "medium")[0] == "medium"
    assert ask(WHEEL, "maybe", "yes")[0] is True
    assert ask(WHEEL, "n")[0] is False


def test_the_end_of_the_input_is_no_answer():
    with pytest.raises(AnswerError, match="no answer"):
        ask(PRESSURE, "x")
