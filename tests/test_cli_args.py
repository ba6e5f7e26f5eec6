"""The argument types and options the commands share (rrfrei/app/commands/args.py).

A bad count or seed is a user error: one line naming the option, the value and what was
expected, exit status 2, the same words from every command that takes it.
"""

from __future__ import annotations

import argparse

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rrfrei.app import cli
from rrfrei.app.commands import args as cargs


@given(st.integers(min_value=-10**6, max_value=10**6), st.integers(min_value=-5, max_value=5))
def test_an_integer_option_takes_every_integer_at_or_above_its_minimum_and_no_other(n, minimum):
    parse = cargs.int_arg(minimum, f"an integer >= {minimum}")
    if n >= minimum:
        assert parse(str(n)) == n
    else:
        with pytest.raises(argparse.ArgumentTypeError, match=f"expected an integer >= {minimum}, got '{n}'"):
            parse(str(n))


@pytest.mark.parametrize("parse, text, message", [
    (cargs.nonneg_int, "-1", "expected a non-negative integer, got '-1'"),
    (cargs.nonneg_int, "x", "expected a non-negative integer, got 'x'"),
    (cargs.positive_int, "0", "expected a positive integer, got '0'"),
    (cargs.positive_int, "2.5", "expected a positive integer, got '2.5'"),
    (cargs.min_int(2), "1", "expected an integer >= 2, got 1 (leave the option out for the default)"),
    (cargs.min_int(2), "two", "expected an integer >= 2, got 'two'"),
    (cargs.int_arg(1, "a positive integer", name="samples"), "0",
     "samples must be a positive integer, got '0'"),
])
def test_a_value_out_of_range_is_named_with_what_was_expected(parse, text, message):
    with pytest.raises(argparse.ArgumentTypeError) as err:
        parse(text)
    assert str(err.value) == message


@pytest.mark.parametrize("argv, line", [
    (["demo", "--seed", "-1"],
     "rrfrei demo: error: argument --seed: expected a non-negative integer, got '-1'"),
    (["calibrate", "t.csv", "--law", "bouc_wen", "--out", "d", "--seed", "x"],
     "rrfrei calibrate: error: argument --seed: expected a non-negative integer, got 'x'"),
    (["compare", "t.csv", "--out", "d", "--steps", "1"],
     "rrfrei compare: error: argument --steps: expected an integer >= 2, got 1 "
     "(leave the option out for the default)"),
    (["gap-validate", "--workers", "0"],
     "rrfrei gap-validate: error: argument --workers: expected a positive integer, got '0'"),
    (["shake-table", "--draws", "0"],
     "rrfrei shake-table: error: argument --draws: expected a positive integer, got '0'"),
    (["propagate", "--posterior", "p", "--building", "b", "--records", "r", "--chunk-size", "0"],
     "rrfrei propagate: error: argument --chunk-size: chunk-size must be a positive integer, got '0'"),
    (["propagate", "--posterior", "p", "--building", "b", "--records", "r", "--seed", "-2"],
     "rrfrei propagate: error: argument --seed: seed must be a non-negative integer, got '-2'"),
    (["gap", "t.csv", "--time-budget", "soon"], None),
])
def test_every_command_rejects_a_bad_count_with_one_line_and_exit_2(argv, line, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    if line is not None:
        assert err == line + "\n"
    else:
        assert err.startswith("rrfrei gap: error: argument --time-budget: ")


def test_each_command_states_its_description_on_one_line_and_keeps_its_json_and_budget_options():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, p in sub.choices.items():
        assert p.description and "\n" not in p.description and "  " not in p.description, name
        assert isinstance(p.formatter_class, type) and issubclass(
            p.formatter_class, argparse.RawDescriptionHelpFormatter), name
    options = {name: {o for a in p._actions for o in a.option_strings} for name, p in sub.choices.items()}
    for name in ("calibrate", "compare", "gap", "propagate", "shake-table", "kernels"):
        assert "--json" in options[name], name
    for name in ("calibrate", "gap", "gap-validate", "shake-table"):
        assert "--time-budget" in options[name], name


def test_paragraph_folds_a_wrapped_block_into_one_line():
    assert cargs.paragraph("\n  one two\nthree   four\n") == "one two three four"
