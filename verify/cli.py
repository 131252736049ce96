"""What the verifier's command lines share: one-line usage errors and defaults in --help."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import NoReturn

from pipeline.exceptions import DataFileError
from pipeline.offline.coefficients import Coefficients, load_coefficients

#: Exit status for bad command-line input (argparse's own convention).
EXIT_USAGE = 2
#: Where ``python -m pipeline.build`` writes the coefficients by default.
DEFAULT_COEFFICIENTS = "results/coefficients.json"


def load_coefficients_for_cli(source: str) -> Coefficients:
    """:func:`pipeline.offline.coefficients.load_coefficients`, with a hint when the default file is missing.

    Raises:
        DataFileError: missing, unreadable or malformed file.
    """
    if source != "paper" and not Path(source).is_file():
        hint = " (run python -m pipeline.build first, or pass --coefficients paper)"
        raise DataFileError(source, "coefficients file not found" + (hint if source == DEFAULT_COEFFICIENTS else ""))
    return load_coefficients(source)


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Appends "(default: ...)" unless the help text already states its default."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "(default" in text or action.default is argparse.SUPPRESS or action.option_strings == ["-h", "--help"]:
            return text
        return super()._get_help_string(action)


class Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line (no usage block) and exit with status 2."""

    def error(self, message: str) -> NoReturn:  # type: ignore[override]
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")
