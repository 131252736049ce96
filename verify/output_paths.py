"""Output paths of the verifier's CLIs, checked before any work starts.

:func:`pipeline.cli.check_output_file` and :func:`pipeline.cli.check_output_folder` judge a path
by its shape and by ``os.access``; for root ``os.access`` says yes to folders such as ``/proc``
where no file can be created. Here the first existing folder on the way is also probed by
creating an anonymous temporary file in it (``tempfile.TemporaryFile``: no name is left behind),
so ``--json /proc/x`` is refused at once with one line.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from pipeline import cli
from pipeline.exceptions import InvalidParameterError


def _first_existing_folder(path: Path) -> Path:
    folder = path.absolute()
    while not folder.exists():
        folder = folder.parent
    return folder


def _probe(folder: Path, option: str, path: Path) -> None:
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise InvalidParameterError(
            option, str(path), f"a path where files can be written (cannot create a file in {folder}: {reason})"
        ) from None


def check_output_file(path: str | Path | None, option: str) -> Path | None:
    """:func:`pipeline.cli.check_output_file`, and a file can really be created on the way to it."""
    checked = cli.check_output_file(path, option)
    if checked is not None:
        _probe(_first_existing_folder(checked.parent), option, checked)
    return checked


def check_output_folder(path: str | Path | None, option: str) -> Path | None:
    """:func:`pipeline.cli.check_output_folder`, and files can really be created in or on the way to it."""
    checked = cli.check_output_folder(path, option)
    if checked is not None:
        _probe(_first_existing_folder(checked), option, checked)
    return checked
