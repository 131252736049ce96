"""Output paths checked before any work: a command that will write a file or a folder proves
first, creating nothing that stays, that it can.

Permissions are probed by creating (and at once removing) a file in the target folder or its
first existing parent: a permission check says little when running as root (``/proc``).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from pipeline.exceptions import InvalidParameterError


def _check_creatable_under(location: Path, option: str, value: str) -> None:
    """``location`` (a folder, existing or not) is, or can be made, a folder where files can be created.

    Permissions are probed by creating (and at once removing) a file in ``location`` or its
    first existing parent: a permission check says little when running as root (``/proc``)."""
    existing = location.absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise InvalidParameterError(option, value, f"a path whose parent {existing} is a folder, not a file")
    try:
        handle, probe = tempfile.mkstemp(prefix=".write-probe-", dir=existing)
        os.close(handle)
        os.unlink(probe)
    except OSError as exc:
        raise InvalidParameterError(
            option, value, f"a path where files can be created ({existing}: {exc.strerror})"
        ) from None


def check_output_folder(folder: str | Path | None, option: str, *, new_parents: bool = True) -> Path | None:
    """Check, before any work and creating nothing, that ``folder`` is or can become a writable folder.

    Args:
        folder: The folder (None passes).
        option: The option's name, for the message.
        new_parents: False: the folder's parent must exist (only the folder itself may be new),
            so that a mistyped parent is refused rather than created.

    Raises:
        InvalidParameterError: the path is a file, under a file, not writable, or (``new_parents``
            False) its parent does not exist.
    """
    if folder is None:
        return None
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise InvalidParameterError(option, str(folder), "a folder, not an existing file")
    if not new_parents and not folder.exists() and not folder.absolute().parent.exists():
        expected = f"a folder in an existing folder ({folder.parent} does not exist)"
        raise InvalidParameterError(option, str(folder), expected)
    _check_creatable_under(folder, option, str(folder))
    return folder


def check_output_file(path: str | Path | None, option: str) -> Path | None:
    """Check, before any work and creating nothing, that ``path`` can be written as a file in an
    existing folder (replacing an existing file). None passes.

    Raises:
        InvalidParameterError: the path is a folder or ends in a separator, its folder does not
            exist or is a file, or it is not writable.
    """
    if path is None:
        return None
    text = os.fspath(path)
    if isinstance(text, str) and text.endswith(("/", os.sep)):
        raise InvalidParameterError(option, text, "a file name, not a folder (it ends in a path separator)")
    path = Path(path)
    if path.is_dir():
        raise InvalidParameterError(option, str(path), "a file name, not a folder")
    folder = path.parent
    if not folder.exists():
        raise InvalidParameterError(option, str(path), f"a file in an existing folder ({folder} does not exist)")
    _check_creatable_under(folder, option, str(path))
    return path
