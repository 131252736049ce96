"""Where a result came from: package versions and file hashes, for provenance blocks."""

from __future__ import annotations

import hashlib
import platform
from importlib import metadata
from pathlib import Path

#: Distributions whose versions shape the numbers.
PACKAGES: tuple[str, ...] = ("twolink-obstacle", "pin", "coal", "numpy", "scipy")


def package_versions(packages: tuple[str, ...] = PACKAGES) -> dict[str, str | None]:
    """Python's version and each installed package's (None if not installed)."""
    versions: dict[str, str | None] = {"python": platform.python_version()}
    for name in packages:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def sha256_file(path: str | Path) -> str | None:
    """SHA-256 of a file's bytes, or None if it cannot be read."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None
