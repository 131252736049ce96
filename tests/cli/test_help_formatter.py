"""The shared CLI scaffold's help (pipeline.cli.HelpFormatter): a default is shown wherever it is a
value, 0 included, and left out for off-by-default flags, absent defaults and help texts that
already state theirs."""

from __future__ import annotations

from pipeline.cli import Parser


def test_defaults_are_shown_when_they_are_values_zero_included() -> None:
    parser = Parser(prog="demo")
    parser.add_argument("--seed", type=int, default=0, help="seed [integer]")
    parser.add_argument("--margin", type=float, default=0.0, help="margin [m]")
    parser.add_argument("--jobs", type=int, default=1, help="workers [count]")
    parser.add_argument("--flag", action="store_true", help="a switch")
    parser.add_argument("--path", default=None, help="a file")
    parser.add_argument("--stated", type=int, default=3, help="stated [count] (default: three)")
    text = " ".join(parser.format_help().split())
    assert "seed [integer] (default: 0)" in text
    assert "margin [m] (default: 0.0)" in text
    assert "workers [count] (default: 1)" in text
    assert "a switch (default" not in text and "a file (default" not in text
    assert text.count("(default: three)") == 1 and "(default: 3)" not in text
