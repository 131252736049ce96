"""Machine code compiled ahead of time for the functions an online query runs, with Numba's JIT
as the fallback.

Numba compiles a function the first time it is needed and caches the machine code on disk, but
a process that loads even cached code first starts Numba's compiler target: about 0.4 s, plus
about 0.3 s for ``scipy.linalg``, which Numba imports for its linear algebra. A query's few
functions are therefore also compiled when the package is built (``setup.py``), by Numba's
``numba.pycc`` from the same Python source, into an extension module beside their module.
Importing that module takes under a millisecond and starts neither Numba nor LLVM.

:class:`NativeModule` names such a module and its exports (:class:`Export`: a Numba dispatcher,
whose Python function is compiled, and its one signature). :meth:`NativeModule.load` returns the
callable of every export:

* the extension module's function, when the module imports and was compiled from the same
  source bytes: ``setup.py`` compiles the sha256 of the source files into the module as a
  constant (``source_digest()``), and :meth:`NativeModule.load` compares it with the sha256 of
  the files it runs with, so an edited source never runs stale machine code;
* else the dispatcher compiled for the signature by Numba's JIT (loaded from its disk cache, or
  compiled the first time), through the entry point of that compilation. Called directly, it
  skips the dispatcher's matching of the arguments' types against its signatures (about a
  quarter of a microsecond a call).

**What a caller must give.** Both routes convert a number to the signature's type and refuse a
non-number with a TypeError (the extension module also converts a numeric string, as ``float``
does), but neither checks an array's layout, and the extension module does not check its dtype
either: an array of another dtype is read as if it were of the signature's, past its end if its
items are smaller. Every caller therefore gives arrays it made itself, of the signature's dtypes
and C-contiguous (the plan, a map's lookup tables, a batch's points), and checks a user's values
before the call.

Both are Numba's compilation of the same Python functions for the same argument types, without
``fastmath``, so LLVM may neither reorder a floating-point operation nor fuse one into another:
the two routes give the same bits, which ``tests/test_native.py`` checks on random queries with
a module it compiles itself. ``numba.pycc`` is pending deprecation in Numba; where it, a C
compiler or the Python headers are missing, the package is built without the extension modules
and its queries run on the JIT, with the same answers.
"""

from __future__ import annotations

import hashlib
import importlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

from pipeline.exceptions import InvalidParameterError

__all__ = ["CompiledFunctions", "Export", "NativeModule"]

#: The name of the export that returns the digest of the sources a module was compiled from.
DIGEST_EXPORT = "source_digest"


@dataclass(frozen=True)
class Export:
    """One function of a native module.

    Attributes:
        name: The name it is exported under.
        dispatcher: The Numba dispatcher (``numba.njit`` without a signature) of its Python source.
        signature: Its one Numba signature, e.g. ``"int64(float64[::1], int64)"``.
    """

    name: str
    dispatcher: Any
    signature: str

    def __post_init__(self) -> None:
        if not self.name.isidentifier() or self.name == DIGEST_EXPORT:
            raise InvalidParameterError("export name", self.name, f"an identifier other than {DIGEST_EXPORT}")
        if not callable(self.dispatcher):
            raise InvalidParameterError(f"export {self.name}", self.dispatcher, "a Numba dispatcher")


@dataclass(frozen=True)
class CompiledFunctions:
    """The callables of a :class:`NativeModule`'s exports.

    Attributes:
        functions: Export name -> callable (read-only).
        ahead_of_time: True if they are the extension module's, False if Numba's JIT's.
    """

    functions: MappingProxyType
    ahead_of_time: bool

    def __getitem__(self, name: str) -> Callable:
        return self.functions[name]


@dataclass(frozen=True)
class NativeModule:
    """An extension module compiled ahead of time from the Python source of some Numba functions.

    Attributes:
        name: The module's full name, e.g. ``"pipeline.online.kernel_native"`` (it lies in the
            package of its sources).
        exports: The functions it holds.
        sources: The files whose bytes its machine code depends on (the modules that define the
            exports and every compiled function they call).
    """

    name: str
    exports: tuple[Export, ...]
    sources: tuple[str, ...]

    def __post_init__(self) -> None:
        if "." not in self.name or not all(part.isidentifier() for part in self.name.split(".")):
            raise InvalidParameterError("native module name", self.name, "a dotted module name")
        if not self.exports or len({e.name for e in self.exports}) != len(self.exports):
            raise InvalidParameterError(
                f"{self.name} exports", [e.name for e in self.exports], "one or more distinct names"
            )
        if not self.sources:
            raise InvalidParameterError(f"{self.name} sources", self.sources, "one or more source files")

    @property
    def _exports_module(self) -> str:
        """The name of the module that defines the exports (``numba.pycc`` compiles from it)."""
        return self.exports[0].dispatcher.py_func.__module__

    def source_digest(self) -> int:
        """The first 7 bytes of the sha256 of the source files' bytes, in order, as a
        non-negative int64."""
        digest = hashlib.sha256()
        for path in self.sources:
            digest.update(Path(path).read_bytes())
        return int.from_bytes(digest.digest()[:7], "big")

    def load(self) -> CompiledFunctions:
        """Every export's callable: the extension module's if it imports and its digest is the
        sources' (module docstring), else the JIT's (compiled for its signature now). Sources
        that cannot be read (e.g. a package shipped without its ``.py`` files) cannot vouch for
        the module: the JIT's too."""
        try:
            native = importlib.import_module(self.name)
            fresh = native.source_digest() == self.source_digest()
        except (ImportError, AttributeError, OSError):
            fresh = False
        if fresh:
            functions = {e.name: getattr(native, e.name) for e in self.exports}
        else:
            functions = {e.name: _jit_entry(e) for e in self.exports}
        return CompiledFunctions(MappingProxyType(functions), ahead_of_time=fresh)

    def compiler(self, output_dir: str | None = None):
        """The ``numba.pycc.CC`` that compiles this module (its exports and ``source_digest()``)
        into ``output_dir`` (:meth:`numba.pycc.CC.compile`; default: beside the exports' module).
        Imports ``numba.pycc``, a dependency of the build, not of a query."""
        from numba.pycc import CC

        compiler = CC(self.name.rpartition(".")[2], source_module=self._exports_module)
        if output_dir is not None:
            compiler.output_dir = output_dir
        for export in self.exports:
            compiler.export(export.name, export.signature)(export.dispatcher.py_func)
        compiler.export(DIGEST_EXPORT, "int64()")(_constant(self.source_digest()))
        return compiler

    def extension(self):
        """The setuptools extension that builds this module with the package (``setup.py``);
        optional: without a C compiler the package is built without it.

        Raises:
            InvalidParameterError: the module is not in the package of its exports' module.
        """
        if self._exports_module.rpartition(".")[0] != self.name.rpartition(".")[0]:
            raise InvalidParameterError(
                "native module name", self.name, f"a module of the package of {self._exports_module}"
            )
        return self.compiler().distutils_extension(optional=True)


def _jit_entry(export: Export) -> Callable:
    """The export's dispatcher compiled for its signature: the entry point of that compilation
    (the dispatcher itself where there is none, e.g. with ``NUMBA_DISABLE_JIT``)."""
    compile_for = getattr(export.dispatcher, "compile", None)
    return export.dispatcher if compile_for is None else compile_for(export.signature)


def _constant(value: int) -> Callable[[], int]:
    """A function of no argument returning ``value`` (Numba compiles it as a constant)."""

    def source_digest() -> int:
        return value

    return source_digest
