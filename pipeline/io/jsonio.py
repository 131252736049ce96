"""Reading and atomically writing the project's JSON files."""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.exceptions import DataFileError, OutputExistsError


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


def json_safe(value: Any) -> Any:
    """Recursively make ``value`` JSON-serialisable (tuples -> lists, non-finite -> None,
    NumPy scalars and arrays -> Python numbers and lists, paths and others -> str)."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, bool | None | str | int):
        return value
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    return str(value)


def dumps(data: Any) -> str:
    """The canonical text of a JSON document: indented, NaN as null, newline-terminated."""
    return json.dumps(json_safe(data), indent=2, allow_nan=False) + "\n"


def new_file_mode(path: Path) -> int:
    """Mode for a file replacing ``path``: the existing file's, else 0o666 minus the umask."""
    try:
        return path.stat().st_mode & 0o777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def write_bytes_atomic(path: str | Path, data: bytes, overwrite: bool = True) -> bool:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename.

    A crash leaves either the old file or the new one, never a half-written one; the new file
    keeps the old one's mode (else 0o666 minus the umask).

    Returns:
        True if an existing file was replaced.

    Raises:
        OutputExistsError: the path is a folder, its parent is a file, or the file exists and
            ``overwrite`` is False.
    """
    path = Path(path)
    if path.is_dir():
        raise OutputExistsError(f"{path} is a directory; expected a file name to write")
    if path.parent.exists() and not path.parent.is_dir():
        raise OutputExistsError(f"{path.parent} is not a directory")
    existed = path.exists()
    mode = new_file_mode(path)
    if existed and not overwrite:
        raise OutputExistsError(f"{path} exists; pass --force to overwrite it")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return existed


def write_text_atomic(path: str | Path, text: str, overwrite: bool = True) -> bool:
    """:func:`write_bytes_atomic` of ``text`` in UTF-8."""
    return write_bytes_atomic(path, text.encode("utf-8"), overwrite)


def write_json_atomic(path: str | Path, data: Any, overwrite: bool = True) -> bool:
    """:func:`write_text_atomic` of :func:`dumps` (data)."""
    return write_text_atomic(path, dumps(data), overwrite)
