"""An agent's start-up memory given back to the operating system once it runs.

Loading the specification, the content languages and the agent's own modules allocates and
frees a great deal before the first behaviour blocks for input; glibc keeps the freed pages of
its heaps resident for later allocations. ``malloc_trim(0)`` hands every whole free page of
every heap back (glibc ≥ 2.8; Rust's allocations, Zenoh's, live in the same heaps). What it
saves: docs/benchmarks.md, "Where the memory goes".
"""

from __future__ import annotations

import gc
import logging
import sys

log = logging.getLogger(__name__)


def give_back_freed_heap() -> bool:
    """Collect garbage, then return the heaps' free pages to the OS with glibc's
    ``malloc_trim(0)``. Returns False, doing only the collection, where there is no glibc
    (another libc, another OS); never raises."""
    gc.collect()
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        trim = ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):  # musl (no malloc_trim) or no libc.so.6
        return False
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    trim(0)
    log.debug("freed heap pages given back")
    return True
