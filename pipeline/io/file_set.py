"""Several files written as one set: all of them, or none.

:func:`write_file_set` writes every file of the set to a temporary file beside its target
first (flushed to disk), and only then renames them into place, keeping each replaced file
aside until the last rename has succeeded. If anything fails or is interrupted (Ctrl-C) at any
point, the folder is put back as it was: the temporary files are removed, replaced files
restored, files that were new removed, and folders the call created removed again. A build
therefore never leaves new coefficients beside an old region map, or half a set.

A file's content may be given as a function: it is called once every other file of the set is
staged (written and flushed), and its result staged last, so that it can report on the writing
itself (the build's timing file measures the time to write the others).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from pipeline.exceptions import OutputExistsError
from pipeline.io.jsonio import new_file_mode

__all__ = ["Content", "WrittenFile", "write_file_set"]

#: A file's content: bytes, text (UTF-8), None (remove the file), or a function giving bytes or
#: text, called after the other files are staged.
Content = bytes | str | None | Callable[[], bytes | str]


@dataclass(frozen=True)
class WrittenFile:
    """One file of a set as written.

    Attributes:
        path: The file's path.
        replaced: True if it replaced an existing file of that name, False if it is new.
    """

    path: Path
    replaced: bool

    def __str__(self) -> str:
        """``replaced PATH`` or ``wrote PATH``."""
        return f"{'replaced' if self.replaced else 'wrote'} {self.path}"

    def __repr__(self) -> str:
        return f"WrittenFile({str(self.path)!r}, replaced={self.replaced})"


def _make_folder(folder: Path) -> list[Path]:
    """mkdir -p; returns the folders it created, outermost first."""
    created = []
    for candidate in reversed([folder, *folder.parents]):
        if not candidate.exists():
            candidate.mkdir()
            created.append(candidate)
    return created


def _remove_created(created: list[Path]) -> None:
    for folder in reversed(created):
        try:
            folder.rmdir()
        except OSError:
            return


def _stage(path: Path, data: bytes) -> Path:
    """``data`` in a temporary file beside ``path``, flushed, with the mode ``path`` will have."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, new_file_mode(path))
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Path(tmp)


def write_file_set(folder: str | Path, files: Mapping[str, Content]) -> tuple[WrittenFile, ...]:
    """Write ``files`` (name in ``folder`` -> content; None: remove that file) as one set.

    Args:
        folder: The folder (created, with its parents, if missing; removed again on failure).
        files: File name -> bytes or text (UTF-8); None to remove an existing file of that name
            as part of the set (e.g. a map that no longer belongs to the new coefficients); or a
            function giving bytes or text, called once the other files are staged.

    Returns:
        For each file written (not removed), in ``files`` order, a :class:`WrittenFile`: its path
        and whether it replaced an existing file.

    Raises:
        OutputExistsError: a target is a folder, or ``folder`` is a file.
        OSError: the files cannot be written (nothing changed).
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise OutputExistsError(f"{folder} is not a directory")
    targets = {name: folder / name for name in files}
    for path in targets.values():
        if path.is_dir():
            raise OutputExistsError(f"{path} is a directory; expected a file name to write")
    created = _make_folder(folder)
    staged: dict[str, Path] = {}
    moved: list[tuple[Path, Path | None]] = []  # (target, its previous content set aside, or None if new)
    try:
        last = [name for name, content in files.items() if callable(content)]
        for name in [name for name in files if name not in last] + last:
            content = files[name]
            content = content() if callable(content) else content
            if content is not None:
                data = content.encode("utf-8") if isinstance(content, str) else bytes(content)
                staged[name] = _stage(targets[name], data)
        for name, path in targets.items():
            aside = Path(tempfile.mktemp(prefix=f".{path.name}.", suffix=".old", dir=folder)) if path.exists() else None
            moved.append((path, aside))
            if aside is not None:
                os.replace(path, aside)
            if name in staged:
                os.replace(staged[name], path)
                del staged[name]
    except BaseException:
        for path, aside in reversed(moved):
            if aside is None:
                path.unlink(missing_ok=True)
            elif aside.exists():
                os.replace(aside, path)
        for tmp in staged.values():
            tmp.unlink(missing_ok=True)
        _remove_created(created)
        raise
    for _, aside in moved:
        if aside is not None:
            aside.unlink(missing_ok=True)
    return tuple(
        WrittenFile(targets[name], aside is not None)
        for (_, aside), name in zip(moved, files, strict=True)
        if files[name] is not None
    )
