"""Worker processes for the work fdid_fmi runs side by side.

One kind of pool for every place that fits in parallel: ``fdid identify``'s structure choice,
``fdid diagnose``'s refits and the fleet's local pool. Each worker limits BLAS (and OpenMP) to
one thread: the pool already keeps every core busy, and the models' matrices are small, so BLAS
threads on top of it only compete for the cores (measured side by side: 14 % less wall time for
``fdid diagnose --jobs 2`` on a 2-core machine). The ``fdid`` command does the same
while it runs a command (its ``main``, the previous limits restored after), so
``--jobs 1`` and ``--jobs 2`` give the same numbers to the last bit; a Python caller's process
keeps whatever threads it has. Dask's nanny starts its workers with one thread too (its
``distributed.nanny.pre-spawn-environ`` setting).
"""
from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from .errors import InputError


def worker_count(workers):
    """``workers`` checked: None means every core (``os.cpu_count()``); otherwise an integer >= 1."""
    if workers is None:
        return max(1, os.cpu_count() or 1)
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise InputError(f"workers must be an integer >= 1 (or None: every core), got {workers!r}",
                         column="workers")
    return int(workers)


def process_pool(workers, mp_context=None) -> ProcessPoolExecutor:
    """A :class:`~concurrent.futures.ProcessPoolExecutor` of ``workers`` processes, one BLAS
    thread each (``mp_context``: the start method's context; None: the platform's default)."""
    return ProcessPoolExecutor(max_workers=workers, mp_context=mp_context,
                               initializer=one_blas_thread)


def one_blas_thread():
    """Limit every BLAS and OpenMP library loaded in this process to one thread, from now on;
    ``with one_blas_thread():`` restores the previous limits at the end of the block."""
    import scipy.linalg  # noqa: F401  -- scipy's own BLAS, loaded so that the limit reaches it
    from threadpoolctl import threadpool_limits
    return threadpool_limits(limits=1)
