"""Functions short enough to read in one sitting: at most five functions of ``pipeline`` and
``verify`` are longer than 80 lines (the compiled cores, which keep one query's arithmetic in one
call, among them), read from the source with ``ast``."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LONGEST_LINES = 80
MOST_LONG_FUNCTIONS = 5


def long_functions(source: str) -> list[tuple[str, int]]:
    """(name, lines) of every function of ``source`` longer than :data:`LONGEST_LINES` lines."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            lines = node.end_lineno - node.lineno + 1
            if lines > LONGEST_LINES:
                found.append((node.name, lines))
    return found


def test_at_most_five_functions_are_longer_than_80_lines() -> None:
    found = [
        f"{path.relative_to(ROOT)}: {name} ({lines} lines)"
        for package in ("pipeline", "verify")
        for path in sorted((ROOT / package).rglob("*.py"))
        for name, lines in long_functions(path.read_text())
    ]
    assert len(found) <= MOST_LONG_FUNCTIONS, found


def test_the_count_sees_a_long_function() -> None:
    body = "\n".join(f"    x{i} = {i}" for i in range(LONGEST_LINES))
    assert long_functions(f"def f():\n{body}\n") == [("f", LONGEST_LINES + 1)]
    assert long_functions("def g():\n    return 1\n") == []
