"""Timing helper shared by the benchmark scripts (best of ``repeat`` runs, wall clock)."""
import time


def timed(fn, repeat=1, clock=time.perf_counter):
    """Return (best time in s over ``repeat`` calls, the last result); wall clock unless ``clock``
    says otherwise (``time.process_time``: this process's CPU time, steadier on a busy machine)."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = clock()
        out = fn()
        best = min(best, clock() - t0)
    return best, out
