"""The FMU's C plumbing against FMI 2.0 / 3.0 Co-Simulation (fmi2Functions.c,
fmi3Functions.c, fdid_instance.c), driven through fmpy's low-level FMU2Slave / FMU3Slave and raw
ctypes calls, on both FMI versions of one hand-built SISO model (built once per module).

What the tests below guard (each fails on templates without it):
  * a doStep that leaves the model state infinite / NaN does not return OK (else the error comes
    first at a later get, never for a master that reads other outputs or none), and GetFMUstate
    hands out no state that SetFMUstate refuses;
  * '#' in a logged message (from a master's string: GUID, log category) is written '##', so a
    master that expands variable references (#r12# / #12#) does not misread it;
  * a deserialized FMU state with inconsistent step flags (steps counted but no doStep taken;
    initial state to be recomputed after a doStep) is refused; accepted, the FMU time would jump
    back to the start time at the next step while the master's time runs on;
  * SetFMUstate refuses an FMU state of another fdid FMU whose states have the same size (same
    model structure, other parameters): the FMU would silently go on with the other model's state.
The other tests pin down behaviour that is correct as it is.
"""
import ctypes
import re
import struct

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, calloc, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, free)
from fmpy.fmi3 import FMU3Slave

import fmu_support as fs
from fdid_fmi.fmu import export_fmu
from fdid_fmi.fmu.build import compiler_available

pytestmark = pytest.mark.skipif(not compiler_available("linux64"), reason="gcc is not installed")

TS = fs.TS
GUID = 64            # serialized state: GUID (64 bytes), then the snapshot
# snapshot layout after the GUID: magic u32, mode i32, start time f64, steps i64, init_dirty i32,
# out_dirty i32, started i32, (pad), nbuf u64, then the state buffer
OFF_STEPS, OFF_INIT_DIRTY, OFF_STARTED = GUID + 16, GUID + 24, GUID + 32


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    d = tmp_path_factory.mktemp("fmu_plumbing")
    out = {}
    for v in (2, 3):
        path = export_fmu(fs.siso_model(), d / f"r{v}.fmu", fmi_version=v)
        out[v] = (read_model_description(str(path)), extract(str(path), str(d / f"x{v}")))
    return out


@pytest.fixture(scope="module")
def other_fmus(tmp_path_factory):
    """FMUs of another model with the same structure (so FMU states of the same size)."""
    d = tmp_path_factory.mktemp("fmu_plumbing_other")
    out = {}
    for v in (2, 3):
        path = export_fmu(fs.siso_model(level=2.0, zeta=0.5), d / f"o{v}.fmu", fmi_version=v)
        out[v] = (read_model_description(str(path)), extract(str(path), str(d / f"x{v}")))
    return out


class Slave:
    """One instance with a logger that records (status, category, message); FMI 2 or 3."""

    def __init__(self, fmus, v, name="r3"):
        md, d = fmus[v]
        self.v, self.md, self.logs = v, md, []
        cls = FMU3Slave if v == 3 else FMU2Slave
        self.f = cls(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                     instanceName=name)
        self.vr = {x.name: x.valueReference for x in md.modelVariables}
        three = v == 3
        self.get = self.f.getFloat64 if three else self.f.getReal
        self.set = self.f.setFloat64 if three else self.f.setReal
        self.get_state = self.f.getFMUState if three else self.f.getFMUstate
        self.set_state = self.f.setFMUState if three else self.f.setFMUstate
        self.serialize = self.f.serializeFMUState if three else self.f.serializeFMUstate
        self.deserialize = self.f.deserializeFMUState if three else self.f.deSerializeFMUstate

    def instantiate(self):
        if self.v == 3:
            self.f.instantiate(loggingOn=True, logMessage=lambda env, status, cat, msg: self.logs.append(
                (status, cat.decode(), msg.decode())))
        else:
            cb = fmi2CallbackFunctions()
            cb.logger = fmi2CallbackLoggerTYPE(lambda env, name, status, cat, msg: self.logs.append(
                (status, cat.decode(), msg.decode())))
            cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            self._cb = cb                                # kept alive while the instance lives
            self.f.instantiate(callbacks=cb, loggingOn=True)
        return self

    def _initialize(self, inputs):
        if self.v == 3:
            self.f.enterInitializationMode(startTime=0.0)
        else:
            self.f.setupExperiment(startTime=0.0)
            self.f.enterInitializationMode()
        for k, x in (inputs or {}).items():
            self.set([self.vr[k]], [x])
        self.f.exitInitializationMode()
        return self

    def start(self, inputs=None):
        self.instantiate()
        return self._initialize(inputs)

    def reset_and_start(self, inputs=None):
        self.f.reset()
        self._initialize(inputs)

    def errors(self):
        return [m for s, c, m in self.logs if s == 3]

    def free(self):
        self.f.freeInstance()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()


def _run(s, cmd, k0=0, outs=("x_x", "x_v", "x_dnf")):
    y = []
    for k in range(k0, len(cmd)):
        s.set([s.vr["x_x_cmd"]], [cmd[k]])
        s.f.doStep(k * TS, TS)
        y.append(s.get([s.vr[o] for o in outs]))
    return np.array(y)


# ----------------------------------------------------------------------------- defects
@pytest.mark.parametrize("v", [2, 3])
def test_a_step_that_makes_the_state_non_finite_is_an_error(fmus, v):
    """Commands of +-1e308 mm (finite, so SetReal accepts them) overflow the state in the second
    step. FMI 2.0.4 2.1.3 (status) / FMI 3.0 4.2.1 (fmi3DoStep, Step Mode): a step the FMU could
    not compute must return fmi2Error / fmi3Error (earlyReturn or OK may not signal it). Returning
    OK with inf/NaN in the state, GetFMUstate would give a state that SetFMUstate refuses, and
    only a later get of an output would report it."""
    with Slave(fmus, v).start() as s:
        first = s.get_state()
        failed_at = None
        for k in range(4):
            s.set([s.vr["x_x_cmd"]], [1e308 if k % 2 == 0 else -1e308])
            try:
                s.f.doStep(k * TS, TS)
            except FMICallException:
                failed_at = k
                break
            s.set_state(s.get_state())           # every state after an OK step can be set again
        assert failed_at is not None, "doStep returned OK with a non-finite model state"
        assert "not finite" in s.errors()[-1] and f"fmi{v}DoStep" in s.errors()[-1]
        with pytest.raises(FMICallException):   # the error state: no further step ...
            s.f.doStep((failed_at + 1) * TS, TS)
        s.set_state(first)                       # ... until an earlier state is restored
        s.set([s.vr["x_x_cmd"]], [0.5])
        s.f.doStep(0.0, TS)
        assert np.all(np.isfinite(s.get([s.vr["x_x"], s.vr["x_v"]])))


def _lone_hash(msg):
    """True when a '#' in msg is not part of a '##' pair (the FMI escape of a literal '#')."""
    return "#" in re.sub("##", "", msg)


@pytest.mark.parametrize("v", [2, 3])
def test_hash_in_a_logged_message_is_escaped(fmus, v):
    """FMI 2.0.4 section 2.1.5 (logger) / FMI 3.0 section 2.3.1 (logMessage): '#' marks a variable
    reference (#r1# / #1#) that the master may expand; a literal '#' must be written '##'. The
    FMU echoes master strings: an unknown log category, a wrong GUID / instantiation token."""
    with Slave(fmus, v).start() as s:
        fn = getattr(s.f.dll, f"fmi{v}SetDebugLogging")
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t, ctypes.POINTER(ctypes.c_char_p)]
        assert fn(s.f.component, 1, 1, (ctypes.c_char_p * 1)(b"my#r1#category")) == 1   # warning
        msg = [m for st, c, m in s.logs if "unknown log category" in m][-1]
        assert "my##r1##category" in msg and not _lone_hash(msg), msg
    w = Slave(fmus, v)
    w.f.guid = "{#1#}"                           # a wrong token holding '#'
    with pytest.raises(Exception):
        w.instantiate()
    assert w.errors() and all(not _lone_hash(m) for m in w.errors()), w.errors()
    assert "{##1##}" in w.errors()[-1]


def _flags(b):
    return (struct.unpack_from("<q", b, OFF_STEPS)[0], struct.unpack_from("<i", b, OFF_INIT_DIRTY)[0],
            struct.unpack_from("<i", b, OFF_STARTED)[0])


@pytest.mark.parametrize("v", [2, 3])
def test_a_state_with_inconsistent_step_flags_is_refused(fmus, v):
    """A serialized state comes from outside and is checked field by field. Steps counted with
    no doStep taken (or an initial state to recompute after one) is no state the FMU can be in:
    accepted, the next output evaluation would re-initialize the model and set the FMU time back
    (lastSuccessfulTime 1 Ts after doStep(5 Ts, Ts))."""
    with Slave(fmus, v).start() as s:
        before = bytes(s.serialize(s.get_state()))      # after ExitInitializationMode, no step
        assert _flags(before) == (0, 0, 0)
        s.f.doStep(0.0, TS)
        after = bytes(s.serialize(s.get_state()))
        assert _flags(after) == (1, 0, 1)
        for good in (before, after):                    # the genuine states are accepted
            s.deserialize(good)
        forged = []
        b = bytearray(before)
        struct.pack_into("<q", b, OFF_STEPS, 5)         # 5 steps, started = 0
        forged.append(b)
        b = bytearray(after)
        struct.pack_into("<i", b, OFF_INIT_DIRTY, 1)    # re-initialize after a step
        forged.append(b)
        b = bytearray(after)
        struct.pack_into("<i", b, GUID + 4, 2)          # initialization mode with a step taken
        forged.append(b)
        for b in forged:
            s.logs.clear()
            with pytest.raises(FMICallException):
                s.deserialize(bytes(b))
            assert "corrupt state" in s.errors()[-1]


@pytest.mark.parametrize("v", [2, 3])
def test_a_state_of_another_fmu_is_refused(fmus, other_fmus, v):
    """FMI 2.0.4 2.1.8 / FMI 3.0 2.2.7.4 (the complete FMU state): SetFMUstate restores a state
    this FMU copied. Two axis FMUs of one structure (a master keeping their states in one array) have
    states of the same size and kind; unchecked, B would take A's state with OK and simulate on
    with A's parameters and A's time. The serialized form is checked as well (GUID)."""
    with Slave(fmus, v, "a").start({"x_x_cmd": 0.3}) as a, Slave(other_fmus, v, "b").start() as b:
        a.f.doStep(0.0, TS)
        sa, sb = a.get_state(), b.get_state()
        with pytest.raises(FMICallException):
            b.set_state(sa)
        assert "not a state of this FMU" in b.errors()[-1]
        b.set_state(sb)                                 # its own state is accepted
        get = getattr(b.f.dll, "fmi3GetFMUState" if v == 3 else "fmi2GetFMUstate")
        get.restype = ctypes.c_int
        get.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_void_p)]
        held = ctypes.c_void_p(sa.value)                # A's state given to B to be overwritten
        assert get(b.f.component, ctypes.byref(held)) == 3 and held.value == sa.value
        b.set_state(sb)
        b.f.doStep(0.0, TS)
        blob = bytes(a.serialize(sa))
        with pytest.raises(FMICallException):           # serialized: refused by the GUID
            b.deserialize(blob)


# ----------------------------------------------------------------------------- checked, correct
@pytest.mark.parametrize("v", [2, 3])
def test_reset_then_rerun_equals_a_fresh_instance_and_states_round_trip(fmus, v):
    cmd = np.cumsum(np.random.default_rng(3).normal(0.0, 0.01, 120))
    ins = {"x_v0": 2.0, "x_friction_level": 0.7, "x_x_cmd": cmd[0]}
    with Slave(fmus, v, "fresh").start(ins) as fresh, Slave(fmus, v, "used").start(ins) as s:
        ref = _run(fresh, cmd)
        _run(s, cmd[:50] * 3.0)                          # a different first run
        s.reset_and_start(ins)
        assert np.array_equal(_run(s, cmd[:60]), ref[:60])
        state = s.get_state()
        blob = bytes(s.serialize(state))
        assert np.array_equal(_run(s, cmd, k0=60), ref[60:])
        s.set_state(state)
        assert np.array_equal(_run(s, cmd, k0=60), ref[60:])
        fresh.reset_and_start(ins)                       # another instance continues the state
        fresh.set_state(fresh.deserialize(blob))
        assert np.array_equal(_run(fresh, cmd, k0=60), ref[60:])
        for bad in (blob[:-1], blob + b"\0", b"", bytes([blob[0] ^ 1]) + blob[1:],   # truncated, long,
                    blob[:GUID] + bytes(len(blob) - GUID)):               # foreign GUID, zeroed body
            with pytest.raises(FMICallException):
                s.deserialize(bad)


@pytest.mark.parametrize("v", [2, 3])
def test_value_references_types_and_null_arrays(fmus, v):
    with Slave(fmus, v).start() as s:
        state = s.get_state()
        for call in (lambda: s.get([len(s.md.modelVariables) + 5]),            # out of range
                     lambda: s.set([s.vr["x_x"]], [1.0]),                       # an output
                     lambda: s.set([s.vr["x_v0"]], [1.0]),                      # fixed, after init
                     lambda: s.set([s.vr["x_x_cmd"]], [float("nan")]),
                     lambda: s.f.getBoolean([s.vr["x_x"]]),                     # a Real as Boolean
                     lambda: (s.f.getInt32 if v == 3 else s.f.getInteger)([s.vr["x_x"]]),
                     lambda: s.f.getString([s.vr["x_x"]])):
            s.logs.clear()
            with pytest.raises(FMICallException):
                call()
            assert s.errors(), "an error without a logged reason"
            s.set_state(state)
        y = s.get([s.vr["x_x"], s.vr["x_x"], s.vr["x_v"], s.vr["x_x"]])          # repeated: fine
        assert y[0] == y[1] == y[3]
        vp = ctypes.c_void_p
        for name in (("fmi3GetFloat64", "fmi3SetFloat64", "fmi3GetBoolean") if v == 3
                     else ("fmi2GetReal", "fmi2SetReal", "fmi2GetBoolean")):
            fn = getattr(s.f.dll, name)
            fn.restype = ctypes.c_int
            if v == 3:
                fn.argtypes = [vp, vp, ctypes.c_size_t, vp, ctypes.c_size_t]
                assert fn(s.f.component, None, 0, None, 0) == 0                 # nothing, NULL arrays
                assert fn(s.f.component, None, 1, None, 1) == 3                 # NULL with n > 0
            else:
                fn.argtypes = [vp, vp, ctypes.c_size_t, vp]
                assert fn(s.f.component, None, 0, None) == 0
                assert fn(s.f.component, None, 1, None) == 3
            s.set_state(state)


def test_fmi3_null_logger_and_null_resource_path(fmus):
    """FMI 3.0 section 2.3.1: logMessage and resourcePath may be NULL."""
    md, d = fmus[3]
    lib = ctypes.CDLL(f"{d}/binaries/x86_64-linux/{md.coSimulation.modelIdentifier}.so")
    inst = lib.fmi3InstantiateCoSimulation
    inst.restype = ctypes.c_void_p
    inst.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_bool, ctypes.c_bool,
                     ctypes.c_bool, ctypes.c_bool, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p,
                     ctypes.c_void_p, ctypes.c_void_p]
    assert inst(b"n", b"{wrong}", None, False, True, False, False, None, 0, None, None, None) is None
    c = inst(b"n", md.guid.encode(), None, False, True, False, False, None, 0, None, None, None)
    assert c
    do_step = lib.fmi3DoStep
    do_step.restype = ctypes.c_int
    do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_bool] + [ctypes.c_void_p] * 4
    assert do_step(c, 0.0, TS, True, None, None, None, None) == 3             # before initialization
    lib.fmi3FreeInstance.argtypes = [ctypes.c_void_p]
    lib.fmi3FreeInstance(c)
