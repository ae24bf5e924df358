"""fdid's worker processes run BLAS on one thread, whatever the environment asks for
(``fdid_fmi.workers``: the pool already fills the cores)."""
import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import pytest

from fdid_fmi.workers import process_pool


def blas_threads():
    """The thread counts of the BLAS libraries loaded in this process."""
    import scipy.linalg  # noqa: F401  -- scipy's own BLAS as well as numpy's
    from threadpoolctl import threadpool_info
    return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]


def test_a_worker_runs_blas_on_one_thread_when_the_environment_asks_for_two(monkeypatch):
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.setenv(var, "2")     # spawned processes read it when BLAS loads
    spawn = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(1, mp_context=spawn) as plain:
        control = plain.submit(blas_threads).result()
    if not control or max(control) < 2:
        pytest.skip(f"this machine's BLAS does not run 2 threads here ({control}): nothing to limit")
    with process_pool(1, spawn) as pool:
        assert pool.submit(blas_threads).result() == [1] * len(control)


def test_the_cli_in_process_leaves_the_callers_blas_threads_as_they_were(tmp_path, capsys):
    from threadpoolctl import threadpool_limits
    from fdid_fmi.cli import main
    with threadpool_limits(limits=2):
        before = blas_threads()
        if max(before) < 2:
            pytest.skip(f"this machine's BLAS does not run 2 threads here ({before}): nothing to restore")
        # a command that loads the model and fails on it: fdid ran, inside its one-thread limit
        assert main(["simulate", str(tmp_path / "missing.json"), str(tmp_path / "missing.csv")]) == 2
        assert "fdid simulate: error" in capsys.readouterr().err
        assert blas_threads() == before
