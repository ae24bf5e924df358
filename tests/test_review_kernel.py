"""Hostile arguments at the compiled core's Python entry points (fdid_fmi.kernel): each call
either gives the documented doubles or a clear error, never a read or write outside its arrays,
into a read-only array, or through memory that was freed."""
import gc

import numpy as np
import pytest
import scipy.signal as ss

import fmu_support as fs
from fdid_fmi import kernel
from fdid_fmi.errors import InputError


@pytest.fixture(scope="module")
def siso():
    return kernel.CompiledModel(fs.siso_model())


def test_stepper_outputs_stay_valid_after_the_stepper_is_gone(siso):
    st = kernel.Stepper(siso)
    nbuf = st._buf.size
    expected = st.outputs().copy()
    del st
    y = kernel.Stepper(siso).outputs()       # the Stepper is dropped at once
    gc.collect()
    # arrays of the buffer's size take the freed block if it was freed
    others = [np.full(nbuf, 123.0) for _ in range(8)]
    assert np.array_equal(y, expected), y
    assert all(np.all(o == 123.0) for o in others)
