"""Reading and atomically writing the project's JSON files."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

from .exceptions import DataFileError, OutputExistsError


def read_json(path: str | Path) -> dict:
    """Parse a JSON object from ``path``.

    Raises:
        DataFileError: the file is missing, unreadable, not JSON, or not an object.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise DataFileError(path, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(path, f"cannot be read ({exc.__class__.__name__}: {exc})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DataFileError(path, f"not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None
    if not isinstance(data, dict):
        raise DataFileError(path, f"expected a JSON object at top level, found {type(data).__name__}")
    return data


def dumps(data: dict) -> str:
    """The canonical text of a JSON document: sorted-free, indented, NaN as null, newline-terminated."""
    return json.dumps(_nan_to_none(data), indent=2, allow_nan=False) + "\n"


def _nan_to_none(value):
    if isinstance(value, float) and value != value:
        return None
    if isinstance(value, dict):
        return {k: _nan_to_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_nan_to_none(v) for v in value]
    return value


def write_text_atomic(path: str | Path, text: str, overwrite: bool = True) -> bool:
    """Write ``text`` to ``path`` through a temporary file in the same folder and a rename.

    A crash leaves either the old file or the new one, never a half-written one.

    Returns:
        True if an existing file was replaced.

    Raises:
        OutputExistsError: the file exists and ``overwrite`` is False.
    """
    path = Path(path)
    existed = path.exists()
    if existed and not overwrite:
        raise OutputExistsError(f"{path} exists; pass --force to overwrite it")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return existed


def write_json_atomic(path: str | Path, data: dict, overwrite: bool = True) -> bool:
    """:func:`write_text_atomic` of :func:`dumps` (data)."""
    return write_text_atomic(path, dumps(data), overwrite)
