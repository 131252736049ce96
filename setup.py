"""The package's extension modules: the online query's machine code, compiled ahead of time by
Numba's ``numba.pycc`` from the package's own source (``pipeline/native.py`` says why and how).

Everything else about the package is declared in ``pyproject.toml``. Where Numba's ``pycc``, a C
compiler or the Python headers are missing, the package is built without the extension modules
(a warning says why) and its queries run on Numba's JIT, with the same answers.
"""

from __future__ import annotations

import importlib
import sys
import types
from pathlib import Path

from setuptools import setup

ROOT = Path(__file__).resolve().parent
#: The modules that declare a native module (their ``NATIVE``), in build order.
DECLARING = ("pipeline.certify.lookup", "pipeline.online.kernel")


def _declaring_modules() -> list[types.ModuleType]:
    """The modules of :data:`DECLARING`, imported without running the package's ``__init__``
    files (which import the runtime's dependencies, absent from the build's environment)."""
    for package in ("pipeline", "pipeline.certify", "pipeline.online"):
        stub = types.ModuleType(package)
        stub.__path__ = [str(ROOT.joinpath(*package.split(".")))]
        sys.modules.setdefault(package, stub)
    return [importlib.import_module(name) for name in DECLARING]


def native_extensions() -> list:
    """The extension modules to build, or none where they cannot be (a warning on stderr)."""
    try:
        modules = _declaring_modules()
        return [module.NATIVE.extension() for module in modules]
    except Exception as error:  # any failure here means: build without them
        print(
            f"warning: building without the ahead-of-time core ({error}); queries run on Numba's JIT", file=sys.stderr
        )
        return []


setup(ext_modules=native_extensions())
