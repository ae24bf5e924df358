"""Timing helper shared by the benchmark scripts (best of ``repeat`` runs, wall clock)."""
import time


def timed(fn, repeat=1):
    """Return (best wall time in s over ``repeat`` calls, the last result)."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out
