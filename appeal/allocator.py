"""Keep freed memory in the process for the next array (glibc's ``M_TOP_PAD``).

A numerical loop that makes and drops arrays of a megabyte or more (a mixed model's 373 × 373
system, its inverse and products: a dozen per deviance evaluation) hands their pages back to the
system when they are freed and takes them again, zero-filled, at the next allocation. On virtual
machines a page fault is expensive: on the project's machines one REML deviance and gradient of
the 10,000-row crossed model took 13 ms with glibc's defaults and 5.6 ms with 64 MiB of heap kept
(``MALLOC_TOP_PAD_``; ``benchmarks/lmm_command.py``). :func:`keep_heap_pad` sets that for the
running process; the ``appeal`` command calls it at start-up. Elsewhere than glibc it does nothing.
"""

from __future__ import annotations

import ctypes
import os

__all__ = ["keep_heap_pad"]

#: glibc's mallopt parameter number for the top pad (malloc.h: M_TOP_PAD -2).
_M_TOP_PAD = -2


def keep_heap_pad(megabytes: int = 64) -> bool:
    """Keep up to ``megabytes`` MiB of freed heap for reuse (``mallopt(M_TOP_PAD, ...)``).

    Returns whether it took effect: False where the C library is not glibc, or where the user set
    ``MALLOC_TOP_PAD_`` (theirs is kept).
    """
    if "MALLOC_TOP_PAD_" in os.environ:
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the process's own symbols: the C library it runs on
    except (OSError, AttributeError, TypeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(_M_TOP_PAD, int(megabytes) << 20))
