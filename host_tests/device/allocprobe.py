"""Allocation probe that runs inside the MicroPython VM (not on CPython).

bytes_per_call(fn, args, n): gc.mem_alloc() before and after n calls, divided by n.
heap_locked(fn, args, n): runs the n calls with the heap locked *inside this function*, so an
allocation raises MemoryError here, where it is caught and reported, instead of at module
level, where this port hangs. Returns None when nothing allocated, else the error text.
"""
import gc

import micropython


def _call(fn, args, n):
    # a while loop: `for i in range(n)` would allocate the range object under the lock
    i = 0
    if len(args) == 0:
        while i < n:
            fn()
            i += 1
    elif len(args) == 1:
        a = args[0]
        while i < n:
            fn(a)
            i += 1
    elif len(args) == 2:
        a, b = args
        while i < n:
            fn(a, b)
            i += 1
    else:
        a, b, c = args
        while i < n:
            fn(a, b, c)
            i += 1


def bytes_per_call(fn, args=(), n=200):
    _call(fn, args, 2)  # warm caches (attribute lookups, lazy set-up)
    gc.collect()
    before = gc.mem_alloc()
    _call(fn, args, n)
    after = gc.mem_alloc()
    return (after - before) / n


def heap_locked(fn, args=(), n=50):
    _call(fn, args, 2)
    gc.collect()
    err = None
    micropython.heap_lock()
    try:
        _call(fn, args, n)
    except MemoryError as e:
        err = e
    finally:
        micropython.heap_unlock()
    if err is None:
        return None
    return "MemoryError under heap_lock: %r" % (err,)


def report(name, fn, args=(), n=200):
    """Print one machine-readable line: ALLOC name bytes_per_call locked_ok."""
    b = bytes_per_call(fn, args, n)
    locked = heap_locked(fn, args, n // 4 + 1)
    print("ALLOC %s %s %s" % (name, b, "ok" if locked is None else "fail"))
