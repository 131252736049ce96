"""The C allocator's mmap threshold in a Dask worker: why the build's tasks ran slower per core
there, and the one call that restores their speed.

A Dask nanny starts its worker with ``MALLOC_TRIM_THRESHOLD_=65536`` (its default
``distributed.nanny.pre-spawn-environ``), so that freed memory goes back to the system. Setting
any of glibc's ``M_TRIM_THRESHOLD``, ``M_TOP_PAD``, ``M_MMAP_THRESHOLD`` or ``M_MMAP_MAX``,
by environment or by ``mallopt``, turns off glibc's *dynamic* mmap threshold: the threshold stays
at its initial 128 KiB instead of rising to the size of the largest block freed. Every NumPy
array above 128 KiB is then a fresh ``mmap`` whose pages fault in on first touch and go back to
the system on ``free``. The range certificate's interval arithmetic makes many temporaries of a
few hundred KiB, so such a process takes longer for the same work: the default build's map,
``python -m pipeline.certify_range results/coefficients.json`` in one process, took 64.4 s with
``MALLOC_TRIM_THRESHOLD_=65536`` in its environment against 50.8 s without it, the two run side by
side.

:func:`raise_mmap_threshold` sets ``M_MMAP_THRESHOLD`` to :data:`MMAP_THRESHOLD_BYTES` (glibc's
largest, 32 MiB on 64-bit): blocks below it come from the heap, whose top is still trimmed at
the worker's trim threshold, so memory still goes back to the system. The call is
process-wide and idempotent; :mod:`pipeline.io.executor` makes it at the start of every chunk
it runs on a Dask worker. Where the C library is not glibc (or not found) it does nothing.

:func:`mmapped_bytes` reads glibc's count of bytes held in mmapped blocks (``mallinfo2``), the
observable that tells the two thresholds apart (the tests use it).
"""

from __future__ import annotations

import ctypes
import os

__all__ = ["MMAP_THRESHOLD_BYTES", "mmapped_bytes", "raise_mmap_threshold"]

#: The mmap threshold set in a Dask worker [bytes]: glibc's maximum on 64-bit
#: (``DEFAULT_MMAP_THRESHOLD_MAX``, 4 MiB x sizeof(long)).
MMAP_THRESHOLD_BYTES = 32 * 1024 * 1024
#: ``mallopt``'s parameter number for the mmap threshold (malloc.h).
_M_MMAP_THRESHOLD = -3


class _MallInfo2(ctypes.Structure):
    """glibc's ``struct mallinfo2`` (2.33 and later): ten ``size_t`` counters."""

    _fields_ = [
        (name, ctypes.c_size_t)
        for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks")
    ] + [("keepcost", ctypes.c_size_t)]


def _glibc() -> ctypes.CDLL | None:
    """This process's global symbols (``dlopen(NULL)``, which hold the C library's) if the C
    library is glibc, else None. Cheap enough for every chunk: no library search, no file read."""
    try:
        version = os.confstr("CS_GNU_LIBC_VERSION")
    except (AttributeError, ValueError, OSError):  # no confstr, or no such name on this platform
        return None
    if not version or not version.startswith("glibc"):
        return None
    try:
        return ctypes.CDLL(None)
    except OSError:
        return None


def raise_mmap_threshold() -> bool:
    """Set this process's mmap threshold to :data:`MMAP_THRESHOLD_BYTES` (module docstring).

    Returns:
        True if glibc accepted it, False where there is no glibc (nothing changed).
    """
    libc = _glibc()
    if libc is None or not hasattr(libc, "mallopt"):
        return False
    return bool(libc.mallopt(ctypes.c_int(_M_MMAP_THRESHOLD), ctypes.c_int(MMAP_THRESHOLD_BYTES)))


def mmapped_bytes() -> int | None:
    """Bytes this process's allocator holds in mmapped blocks (glibc's ``mallinfo2().hblkhd``),
    or None where there is no glibc 2.33+ [bytes]."""
    libc = _glibc()
    if libc is None or not hasattr(libc, "mallinfo2"):
        return None
    libc.mallinfo2.restype = _MallInfo2
    return int(libc.mallinfo2().hblkhd)
