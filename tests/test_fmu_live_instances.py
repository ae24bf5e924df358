"""An instance freed twice, used after it was freed, or a pointer that never was an instance is
refused (the FMU keeps a registry of its live instances) instead of crashing the master; other
instances of the same FMU go on. FMI 2 and FMI 3, called through ctypes in a child process, so
that a crash fails the test instead of ending the test run."""
import subprocess
import sys

import pytest

import fmu_support as fs
from fdid_fmi.fmu import export_fmu
from fdid_fmi.fmu.build import compiler_available

pytestmark = pytest.mark.skipif(not compiler_available("linux64"), reason="gcc is not installed")

HOST = r'''
import ctypes, os, sys
from ctypes import POINTER, byref, c_double, c_int, c_size_t, c_uint32, c_void_p
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

fmu = sys.argv[1]
md = read_model_description(fmu)
d = extract(fmu, sys.argv[2])
three = md.fmiVersion.startswith("3")
cls = FMU3Slave if three else FMU2Slave
vr = {v.name: v.valueReference for v in md.modelVariables}
kw = dict(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier)
a, b = cls(instanceName="a", **kw), cls(instanceName="b", **kw)
a.instantiate(loggingOn=False)
b.instantiate(loggingOn=False)
lib = a.dll
P = "fmi3" if three else "fmi2"
free_instance = getattr(lib, P + "FreeInstance")
free_instance.argtypes, free_instance.restype = [c_void_p], None
do_step = getattr(lib, P + "DoStep")
if three:
    do_step.argtypes = [c_void_p, c_double, c_double, c_int, c_void_p, c_void_p, c_void_p, c_void_p]
    step = lambda c: do_step(c, 0.0, 1e-3, 0, None, None, None, None)
else:
    do_step.argtypes = [c_void_p, c_double, c_double, c_int]
    step = lambda c: do_step(c, 0.0, 1e-3, 0)
do_step.restype = c_int
get = getattr(lib, P + ("GetFloat64" if three else "GetReal"))
get.restype = c_int
vals = (c_double * 1)()
vrs = (c_uint32 * 1)(vr["x_x"])
read = (lambda c: get(c_void_p(c), vrs, c_size_t(1), vals, c_size_t(1))) if three else \
       (lambda c: get(c_void_p(c), vrs, c_size_t(1), vals))
debug = getattr(lib, P + "SetDebugLogging")
debug.argtypes, debug.restype = [c_void_p, c_int, c_size_t, c_void_p], c_int
reset = getattr(lib, P + "Reset")
reset.argtypes, reset.restype = [c_void_p], c_int

ca = a.component.value if hasattr(a.component, "value") else a.component
free_instance(ca)
free_instance(ca)                                   # freed twice
results = [step(ca), read(ca), debug(ca, 1, 0, None), reset(ca)]   # used after it was freed
fake = ctypes.create_string_buffer(4096)            # never an instance
addr = ctypes.addressof(fake)
results += [step(addr), read(addr), reset(addr)]
free_instance(addr)
print("refused", results)
# the other instance is untouched
if three:
    b.enterInitializationMode(startTime=0.0)
else:
    b.setupExperiment(startTime=0.0)
    b.enterInitializationMode()
b.exitInitializationMode()
print("live", step(b.component.value if hasattr(b.component, "value") else b.component))
b.freeInstance()
sys.stdout.flush()
os._exit(0)
'''


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    d = tmp_path_factory.mktemp("live")
    m = fs.siso_model()
    return {v: export_fmu(m, d / f"s{v}.fmu", fmi_version=v) for v in (2, 3)}


@pytest.mark.parametrize("version", [2, 3])
def test_freed_or_unknown_instances_are_refused_not_touched(fmus, version, tmp_path):
    host = tmp_path / "host.py"
    host.write_text(HOST)
    proc = subprocess.run([sys.executable, str(host), str(fmus[version]), str(tmp_path / "fmu")], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, (proc.returncode, proc.stdout, proc.stderr[-2000:])
    assert "refused [3, 3, 3, 3, 3, 3, 3]" in proc.stdout, proc.stdout      # fmi2Error / fmi3Error each
    assert "live 0" in proc.stdout, proc.stdout                                # fmi2OK / fmi3OK
