"""Keep freed memory in the process while numerics run, and give it back between a
campaign's phases: glibc malloc tuning for batch numerics.

A step on a 1e5-run batch allocates and frees a few dozen 0.8 MB temporaries. glibc's
defaults hand such blocks back to the kernel as soon as the top of the heap holds a
few MB free (``M_TRIM_THRESHOLD``, adjusted upward only by mmapped frees), so the next
step page-faults them in again: on a VM guest that costs as much as the arithmetic
(docs/benchmarks.md). Fixing the
thresholds keeps those pages in the heap; blocks above 32 MiB (trajectory stores) are
still mmapped and returned on free.
"""

from __future__ import annotations

import ctypes
import sys

_M_TRIM_THRESHOLD = -1  # mallopt parameters, <malloc.h>
_M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD = 32 << 20  # glibc's own upper limit for its dynamic threshold
TRIM_THRESHOLD = 256 << 20  # free heap kept before giving memory back to the kernel

_done: bool | None = None


def keep_freed_memory() -> bool:
    """Set the thresholds once per process; True if this libc took them (glibc),
    False elsewhere (other platforms run correctly, only slower)."""
    global _done
    if _done is None:
        _done = False
        mallopt = _glibc("mallopt", ctypes.c_int, ctypes.c_int)
        if mallopt is not None:
            _done = bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
    return _done


def release_freed_memory() -> bool:
    """Give the free heap back to the kernel (glibc ``malloc_trim``), at the boundaries
    of a campaign's phases (a checkpoint, the end), where no step's temporaries are
    about to be allocated again. The thresholds above keep up to TRIM_THRESHOLD free at
    the top of the heap and every freed block below MMAP_THRESHOLD inside it, which at the
    end of a fine campaign is a large part of its RSS. True if this libc has it."""
    trim = _glibc("malloc_trim", ctypes.c_size_t)
    if trim is None:
        return False
    trim(0)
    return True


def _glibc(name: str, *argtypes):
    """The C library's function ``name`` on Linux, or None (other platforms, or a libc
    without it, e.g. musl: they run correctly, only with more memory or slower)."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        function = getattr(ctypes.CDLL(None), name)
    except (OSError, AttributeError):
        return None
    function.argtypes = argtypes
    return function
