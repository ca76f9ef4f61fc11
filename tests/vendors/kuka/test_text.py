"""app.vendors.kuka.text: KRL structure values as ShowVar prints them, read and written
back, and what a text that is not one is refused with (KUKA System Software 8, "Data types:
STRUC", "Aggregates": ``{FRAME: X 0.0,Y 0.0,...}``, enum values ``#NONE``)."""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from types import FrameType

import pytest
from numpy.testing import assert_allclose

from app.errors import InvalidInput
from app.vendors.kuka.text import (
    KrlSyntaxError,
    format_real,
    format_struct,
    numbers,
    parse,
    parse_struct,
)

#: A $LOAD-like value with members that are not numbers: an enum, a boolean, a nested FRAME.
MIXED = "{LOAD: M 5.5,CM {FRAME: X 1.0,Y 0.0,Z 60.0},NAME #NONE,ON TRUE}"


@pytest.fixture(autouse=True)
def _read_within_5_s() -> Iterator[None]:
    """A controller's text is read within a request: a reader that stops advancing hangs
    it. Each test here fails after 5 s (SIGALRM in the main thread) instead of hanging."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(_signum: int, _frame: FrameType | None) -> None:
        raise TimeoutError("the KRL reader was still reading after 5 s")

    previous = signal.signal(signal.SIGALRM, stop)
    signal.setitimer(signal.ITIMER_REAL, 5.0)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def test_members_that_are_not_numbers_stay_their_text_and_write_back() -> None:
    struct = parse_struct(MIXED)
    assert struct == {
        "M": 5.5,
        "CM": {"X": 1.0, "Y": 0.0, "Z": 60.0},
        "NAME": "#NONE",
        "ON": "TRUE",
    }
    written = format_struct(struct)
    assert written == ("{M 5.500000,CM {X 1.000000,Y 0.0,Z 60.000000},NAME #NONE,ON TRUE}")
    assert parse_struct(written) == struct


@pytest.mark.parametrize("text", ["{}", " { } ", "{FRAME:}", "{FRAME: }"])
def test_an_empty_structure_is_an_empty_dict(text: str) -> None:
    assert parse_struct(text) == {}


def test_the_type_name_and_the_spaces_are_optional() -> None:
    assert parse_struct("{ X 1.5 , Y -2 ,Z 3e2 }") == {"X": 1.5, "Y": -2.0, "Z": 300.0}
    assert parse_struct("{FRAME:X 1.5}") == {"X": 1.5}


@pytest.mark.parametrize(
    ("text", "said"),
    [
        ("{X 1.0,}", "expected a name at 7 of '{X 1.0,}'"),
        ("{X ,Y 1}", "a member without a value at 3 of '{X ,Y 1}'"),
        ("{X 1} Y 2", "unexpected text after the structure: 'Y 2'"),
        ("X 1}", "expected '{' at 0 of 'X 1}', got 'X 1}'"),
        ("{X 1", "expected '}' at 4 of '{X 1', got 'the end'"),
        ("{X {Y 1}", "expected '}' at 8 of '{X {Y 1}', got 'the end'"),
    ],
)
def test_a_text_that_is_not_a_structure_is_refused_saying_where(text: str, said: str) -> None:
    with pytest.raises(KrlSyntaxError) as refused:
        parse_struct(text)
    assert str(refused.value) == said


def test_numbers_names_the_member_that_is_not_one() -> None:
    struct = parse_struct(MIXED)
    assert numbers(struct, ("M",), what="the load") == (5.5,)
    with pytest.raises(KrlSyntaxError) as refused:
        numbers(struct, ("M", "NAME"), what="the load")
    assert str(refused.value).startswith("the load has no number NAME: {")
    with pytest.raises(KrlSyntaxError, match="the load has no number MASS"):
        numbers(struct, ("MASS",), what="the load")


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (150.0, "150.000000"),
        (-0.0, "0.0"),
        (-4e-7, "0.0"),
        (4e-7, "0.0"),
        (1e20, "1" + "0" * 20 + ".000000"),
    ],
)
def test_a_real_is_written_in_six_decimals_without_an_exponent(value: float, text: str) -> None:
    assert format_real(value) == text


@pytest.mark.parametrize("value", [float("nan"), float("inf"), float("-inf")])
def test_a_real_that_krl_cannot_hold_is_refused(value: float) -> None:
    with pytest.raises(ValueError, match="cannot be written to a KRL REAL"):
        format_real(value)


def test_the_tool_text_is_found_in_a_config_dat_line_in_any_case() -> None:
    text = "DECL FRAME tool_data[4]={FRAME: X 1.0,Y 2.0,Z 150.0,A 0.0,B 0.0,C 0.0} ; torch"
    position, quaternion = parse(text)
    assert_allclose(position, [1.0, 2.0, 150.0])
    assert_allclose(quaternion, [1.0, 0.0, 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("hello robot", "$TOOL_DATA[n]={X x,Y y,Z z,A a,B b,C c}"),
        ("MY_TOOL_DATA[1]={X 1,Y 2,Z 3,A 0,B 0,C 0}", "$TOOL_DATA[n]={X x,Y y,Z z,A a,B b,C c}"),
        ("$TOOL_DATA[1]={X 1,Y 2,Z 3,A 0,B 0}", "$TOOL_DATA[n]={X x,Y y,Z z,A a,B b,C c}"),
        ("$TOOL_DATA[1]={X 1,Y 2,Z 3,A 0,B 0,C #NONE}", "$TOOL_DATA[n]={X x,Y y,Z z,A a,B b,C c}"),
        (
            "$TOOL_DATA[1]={X 1,Y 2,Z inf,A 0,B 0,C 0}",
            "finite numbers in $TOOL_DATA[n]={X x,...,C c}",
        ),
    ],
)
def test_a_tool_text_that_is_not_one_is_refused_naming_what_was_expected(
    text: str, expected: str
) -> None:
    with pytest.raises(InvalidInput) as refused:
        parse(text)
    assert refused.value.kind == "invalid-pose"
    assert refused.value.loc == ("text",)
    assert refused.value.detail == f"cannot read kuka tool data: expected {expected}, got {text!r}"
