"""The worker pool of a diagnosis's refits (``diagnose.refits.Refits``): errors in a worker reach
the caller as themselves, a bad worker count is one error. That the refits in worker processes
give the same diagnosis as in one process is a check of ``benchmarks/bench_end_to_end.py``
(``checks/diagnose_workers.py``) and of ``benchmarks/bench_diagnose.py``."""
import pytest

from fdid_fmi.diagnose.refits import Refits
from fdid_fmi.errors import InputError
from fdid_fmi.workers import worker_count


def test_an_input_error_in_a_worker_reaches_the_caller_as_itself():
    with Refits(2) as refits:
        fut = refits.submit(worker_count, 0)
        with pytest.raises(InputError, match="workers must be an integer >= 1"):
            fut.result()


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_a_bad_worker_count_is_one_error_naming_it(bad):
    with pytest.raises(InputError, match="column 'workers'"):
        Refits(bad)
