"""A diagnosis's independent refits, side by side in worker processes.

Most of a diagnosis's time is refits that do not depend on each other: the dead time's command
shifts (three refits per shift), the Stribeck velocity's grid and the play's widths, and each
round's null refit and candidate trials with their references. :class:`Refits` runs them in
``workers`` processes (:func:`fdid_fmi.workers.process_pool`: the platform's start method, one
BLAS thread per worker, the same kind of pool as ``fdid identify``'s structure choice) or, with one
worker, in this process, one after the other as they are submitted. A refit is the same
deterministic search wherever it runs (fixed seeds, the same arrays pickled to the worker), so a
diagnosis gives the same result for any number of workers (``tests/test_diagnose_workers.py``),
to the last bit when the calling process, too, runs BLAS on one thread (threaded BLAS sums
round differently).
What is submitted must pickle: module-level functions and ``functools.partial`` of them.
"""
from __future__ import annotations

from concurrent.futures import Future

from ..workers import process_pool, worker_count


class Refits:
    """Independent refits of one diagnosis, in ``workers`` processes (1: in this process).

    Use as a context manager (the pool is shut down on exit). ``submit`` returns a
    :class:`concurrent.futures.Future`; in this process the call has already run and the future
    holds its result or its exception, so callers handle both ways alike.
    """

    def __init__(self, workers=1):
        self.workers = worker_count(workers)
        self._pool = None           # started by the first submit

    def submit(self, fn, *args, **kwargs) -> Future:
        if self.workers > 1:
            if self._pool is None:
                self._pool = process_pool(self.workers)
            return self._pool.submit(fn, *args, **kwargs)
        fut = Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except Exception as exc:        # delivered by fut.result(), as from a worker
            fut.set_exception(exc)
        return fut

    def map(self, fn, items):
        """[fn(x) for x in items], the calls submitted together (exceptions raised in order)."""
        return [f.result() for f in [self.submit(fn, x) for x in items]]

    def close(self):
        """Shut the pool down: refits still queued are cancelled, so an error or an interrupt
        waits only for the refits already started, not for the rest of a scan."""
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
