"""The compiled simulation core, in process: ``fmu_templates/fdid_core.c`` through ctypes.

The step of a DriveModel is written once, in C; every FMU compiles that file, and the package
builds it at install time as the extension ``fdid_fmi._kernel`` (pyproject.toml). This module
turns a DriveModel into the core's ``FdidModel`` (the same :func:`~fdid_fmi.fmu.layout.build_layout`
the FMU generator uses, so port indices and defaults agree) and runs it:

- :func:`run` a whole record (``fdid_run``: set inputs of sample k, read outputs, advance);
- :class:`Stepper` one step at a time (the pythonfmu backend).

The pole search's regressor filter (``kernel_ext/ls_filter.c``: :func:`allpole`,
:func:`regressor_rows`) is built into the same extension.

Both give the doubles an FMU of the same model gives: the same C, compiled with
``-ffp-contract=off`` (no fused multiply-add), on the same data.
"""
from __future__ import annotations

import ctypes as ct
import functools
import numbers
import operator

import numpy as np

from .errors import FdidError, InputError, finite_number
from .model import vtilde_floor_message

_D = ct.POINTER(ct.c_double)
_I = ct.POINTER(ct.c_int)


class _Input(ct.Structure):
    _fields_ = [("kind", ct.c_int), ("axis", ct.c_int), ("function", ct.c_int),
                ("source_position", ct.c_int), ("v_tilde", ct.c_double), ("v_s", ct.c_double),
                ("period_mm", ct.c_double), ("width_mm", ct.c_double)]


class _Rows(ct.Structure):
    _fields_ = [("start", _I), ("col", _I), ("val", _D)]


class _Model(ct.Structure):
    _fields_ = [("model_identifier", ct.c_char_p), ("guid", ct.c_char_p), ("Ts", ct.c_double),
                ("n", ct.c_int), ("m", ct.c_int), ("p", ct.c_int), ("n_axes", ct.c_int),
                ("C", _D), ("D", _D), ("S", _D), ("S2", _D), ("G1", _D),
                ("AB_rows", _Rows), ("CD_rows", _Rows),
                ("inputs", ct.POINTER(_Input)), ("n_fric", ct.c_int),
                ("fric_input", _I), ("fric_vel_output", _I), ("fric_vel_diff", _I),
                ("axis_cmd_input", _I), ("axis_pos_output", _I), ("axis_err_output", _I),
                ("axis_vel_output", _I), ("axis_tool_output", _I),
                ("axis_level0", _D), ("axis_vtilde0", _D), ("axis_vtilde_floor", _D),
                ("n_vars", ct.c_int), ("vars", ct.c_void_p)]


class _Flags(ct.Structure):
    _fields_ = [("steps", ct.c_longlong), ("init_dirty", ct.c_int), ("out_dirty", ct.c_int),
                ("started", ct.c_int)]


_VIEWS = ("xi", "x_prev", "v_prev", "cmd", "ext", "uref", "yoff", "u", "y", "vel",
          "level", "vtilde", "on", "v0", "hold", "work_n", "work_m")


class _State(ct.Structure):
    _fields_ = [("M", ct.POINTER(_Model)), ("f", _Flags), ("nbuf", ct.c_size_t), ("buf", _D)] + \
               [(v, _D) for v in _VIEWS]


@functools.lru_cache(maxsize=1)
def _lib():
    """The core library, with argument types declared and the struct layouts checked."""
    try:
        from . import _kernel
    except ImportError as exc:  # a source tree that was never built
        raise FdidError("the compiled simulation core fdid_fmi._kernel is missing: install the "
                        f"package (pip install .), which builds it ({exc})") from None
    lib = ct.CDLL(_kernel.__file__)
    sp = ct.POINTER(_State)
    lib.fdid_buffer_size.restype = ct.c_size_t
    lib.fdid_buffer_size.argtypes = [ct.POINTER(_Model)]
    lib.fdid_state_bind.argtypes = [sp, ct.POINTER(_Model), _D]
    for f in ("fdid_state_defaults", "fdid_initialize", "fdid_outputs", "fdid_advance"):
        getattr(lib, f).argtypes = [sp]
    lib.fdid_unresolved_friction.argtypes = [sp]
    lib.fdid_run.restype = None
    lib.fdid_run.argtypes = [sp, ct.c_longlong, _D, _D, _D, _D, _D]
    lib.fdid_allpole.restype = lib.fdid_regressor_rows.restype = None
    # the pole search calls these at every pole set: arrays go as addresses (c_void_p), the
    # cheapest conversion ctypes has
    vp = ct.c_void_p
    lib.fdid_allpole.argtypes = [ct.c_int, ct.c_double, vp, ct.c_int, ct.c_longlong, vp, vp, vp]
    lib.fdid_regressor_rows.argtypes = [ct.c_int, ct.c_longlong, ct.c_longlong, ct.c_longlong, vp,
                                        ct.c_int, vp, vp, vp, vp, vp, vp]
    lib.fdid_sizeof_state.restype = lib.fdid_sizeof_model.restype = ct.c_size_t
    if lib.fdid_sizeof_state() != ct.sizeof(_State) or lib.fdid_sizeof_model() != ct.sizeof(_Model):
        raise FdidError("fdid_fmi._kernel was built from other C sources than this package "
                        "(struct sizes differ): reinstall the package")
    return lib


def _real(a, name, ncols=None):
    """``a`` as C-contiguous float64 (a copy where needed), else InputError naming ``name``: real
    numbers only (complex ones would lose their imaginary part); a vector is one column when
    ``ncols`` is 1."""
    try:
        a = np.asarray(a)
        if a.dtype.kind == "c":
            raise TypeError("complex numbers")
        a = np.ascontiguousarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"expected real numbers ({exc})", column=name) from None
    return a.reshape(-1, 1) if ncols == 1 and a.ndim == 1 else a


def _dptr(a):
    return a.ctypes.data_as(_D)


def _iarr(values):
    return np.ascontiguousarray(values if len(values) else [0], dtype=np.intc)


class CompiledModel:
    """A DriveModel as the C core's ``FdidModel`` (arrays kept alive with it).

    Parameters
    ----------
    model : DriveModel  (checked like an FMU export: ``fmu.layout.check_exportable``)
    """

    def __init__(self, model):
        from .fmu.layout import FEATURES, KINDS, build_layout, step_rows
        lay = build_layout(model)
        self.model, self.layout = model, lay
        S, S2, G1 = model.steady_state_maps()
        # copies (not views of the model's C and D: the step's [C D] rows are copies, so a model
        # changed after compiling would run half old, half new)
        self._keep = [np.array(x, dtype=float).ravel() if np.size(x) else np.zeros(1)
                      for x in (model.C, model.D, S, S2, G1)]
        aidx = {a: i for i, a in enumerate(lay.axes)}
        ins = (_Input * max(1, len(model.inputs)))()
        for i, p in enumerate(model.inputs):
            feat = p.kind == "feature"
            ins[i] = _Input(KINDS.index(p.kind), aidx.get(p.axis, -1),
                            FEATURES.index(p.params["function"]) if feat else 0,
                            int(feat and p.params.get("source", "command") == "position"),
                            float(p.params.get("v_tilde", 1.0)) if feat else 1.0,
                            float(p.params.get("v_s", 1.0)) if feat else 1.0,
                            float(p.params.get("period_mm", 1.0)) if feat else 1.0,
                            float(p.params.get("width_mm", 1.0)) if feat else 1.0)
        ints = [_iarr(v) for v in (lay.fric_inputs, lay.fric_vel_output, lay.fric_vel_diff, lay.axis_cmd,
                                   lay.axis_pos, lay.axis_err, lay.axis_vel, lay.axis_tool)]
        dbls = [np.ascontiguousarray(v, dtype=float) for v in (lay.axis_level0, lay.axis_vtilde0,
                                                                  lay.axis_vtilde_floor)]
        self._keep += [ins, *ints, *dbls]
        C, D, S_, S2_, G1_ = (_dptr(x) for x in self._keep[:5])
        csr = [(_iarr(st), _iarr(col), np.ascontiguousarray(val if len(val) else [0.0]))
               for st, col, val in step_rows(model)]
        self._keep += csr
        rows = [_Rows(st.ctypes.data_as(_I), col.ctypes.data_as(_I), _dptr(val)) for st, col, val in csr]
        self.c = _Model(b"kernel", b"", float(model.Ts), model.n_states, len(model.inputs),
                        len(model.outputs), len(lay.axes), C, D, S_, S2_, G1_, *rows, ins,
                        len(lay.fric_inputs), *(x.ctypes.data_as(_I) for x in ints),
                        *(_dptr(x) for x in dbls), 0, None)


class Stepper:
    """One instance of the core: set inputs, read outputs, advance (what an FMU does).

    Parameters
    ----------
    compiled : CompiledModel
    """

    def __init__(self, compiled):
        if not isinstance(compiled, CompiledModel):
            raise InputError(f"expected a CompiledModel (kernel.CompiledModel(model)), got "
                             f"{type(compiled).__name__}", column="compiled")
        lib = _lib()
        self.cm = compiled
        self._buf = np.zeros(max(1, lib.fdid_buffer_size(ct.byref(compiled.c))))
        self.s = _State()
        lib.fdid_state_bind(ct.byref(self.s), ct.byref(compiled.c), _dptr(self._buf))
        lib.fdid_state_defaults(ct.byref(self.s))
        na, m, p = len(compiled.layout.axes), len(compiled.model.inputs), len(compiled.model.outputs)
        base = self._buf.ctypes.data
        v = {}
        for name, size in (("cmd", na), ("ext", max(m, 1)), ("level", na), ("vtilde", na), ("on", na),
                           ("v0", na), ("y", max(p, 1)), ("u", max(m, 1)), ("vel", na)):
            # slices of the buffer itself (not ctypes views of its address): a view handed out
            # (outputs() returns one) keeps the buffer alive after the Stepper is gone
            off = (ct.cast(getattr(self.s, name), ct.c_void_p).value - base) // self._buf.itemsize
            v[name] = self._buf[off:off + size]
        self.views = v          # numpy views into the C state (writing them sets the inputs)

    def set_parameters(self, params, axes):
        """``<axis>_friction_on / _friction_level / _v_tilde`` overrides (the FMU parameters),
        checked as the FMU checks them (level finite and >= 0, v_tilde finite and > 0, and at least
        the level times the model's floor, :meth:`check_friction_resolution`); an
        unknown name is an error, not ignored; so are these names for an axis without friction
        (the FMU has no such parameter; the core would ignore the value) and a ``friction_on``
        that is not a boolean (the string ``"false"`` would have meant on)."""
        names = ("friction_on", "friction_level", "v_tilde")
        fric = {self.cm.model.inputs[i].axis for i in self.cm.layout.fric_inputs}
        known = {f"{a}_{p}" for a in axes if a in fric for p in names}
        unknown = sorted(set(params) - known)
        if unknown:
            frictionless = sorted(a for a in axes if a not in fric
                                  and any(f"{a}_{p}" in params for p in names))
            why = f" (axes {frictionless} have no friction input)" if frictionless else ""
            raise InputError(f"unknown parameter(s) {unknown}{why}; expected some of {sorted(known)}",
                             column="params")
        for a in axes:
            on = params.get(f"{a}_friction_on", False)
            if not (isinstance(on, (bool, np.bool_)) or (isinstance(on, numbers.Real) and on in (0, 1))):
                raise InputError(f"must be true or false (or 1 / 0), got {on!r}", column=f"{a}_friction_on")
        for k, a in enumerate(axes):
            if f"{a}_friction_level" in params:
                lv = finite_number(params[f"{a}_friction_level"], f"{a}_friction_level")
                if not lv >= 0:
                    raise InputError(f"the friction level must be finite and >= 0, got {lv!r}",
                                     column=f"{a}_friction_level")
                self.views["level"][k] = lv
            if f"{a}_v_tilde" in params:
                vt = finite_number(params[f"{a}_v_tilde"], f"{a}_v_tilde")
                if not vt > 0:
                    raise InputError(f"v_tilde must be > 0 mm/s, got {vt!r}", column=f"{a}_v_tilde")
                self.views["vtilde"][k] = vt
            if f"{a}_friction_on" in params:
                self.views["on"][k] = 1.0 if params[f"{a}_friction_on"] else 0.0
        self.check_friction_resolution()

    def check_friction_resolution(self):
        """InputError naming ``<axis>_v_tilde`` when friction is on with a v_tilde below its level
        times the model's floor (``fdid_unresolved_friction``, model.vtilde_floor_per_level)."""
        k = _lib().fdid_unresolved_friction(ct.byref(self.s))
        if k >= 0:
            floor = self.cm.layout.axis_vtilde_floor[k]
            vt, lv = float(self.views["vtilde"][k]), float(self.views["level"][k])
            raise InputError(vtilde_floor_message(vt, lv, floor, len(self.cm.layout.fric_inputs)),
                             column=f"{self.cm.layout.axes[k]}_v_tilde")

    def touch(self, initial=False):
        """Inputs or parameters changed: outputs (and, before the first step, the start) are due."""
        self.s.f.out_dirty = 1
        if initial:
            self.s.f.init_dirty = 1

    def outputs(self):
        _lib().fdid_outputs(ct.byref(self.s))
        return self.views["y"]

    def advance(self):
        _lib().fdid_advance(ct.byref(self.s))

    def copy(self):
        """A second instance of the core in this one's state (its buffer, parameters and flags):
        stepped on, it continues as this one would, which stays where it is."""
        other = Stepper(self.cm)
        other._buf[:] = self._buf
        ct.memmove(ct.addressof(other.s.f), ct.addressof(self.s.f), ct.sizeof(self.s.f))
        return other


def run(compiled, cmds, exts, v0, params=None):
    """Free run of a record through the C core (``fdid_run``).

    Parameters
    ----------
    compiled : CompiledModel
    cmds : (N, n_axes) commanded positions, mm, in the layout's axis order
    exts : (N, m) values of the external inputs in their model-input columns (others ignored)
    v0 : (n_axes,) start velocities, mm/s
    params : dict, optional, FMU parameter overrides (see :meth:`Stepper.set_parameters`)

    Returns
    -------
    Y (N, p) outputs, U (N, m) applied inputs, V (N, n_axes) axis velocities, mm/s
    """
    st = Stepper(compiled)
    axes = compiled.layout.axes
    st.set_parameters(params or {}, axes)
    na, m, p = len(axes), len(compiled.model.inputs), len(compiled.model.outputs)
    # the C reads N x n_axes commands and N x m externals: other shapes are refused, not read
    # past their end (a single axis / input may come as a vector)
    cmds = _real(cmds, "cmds", ncols=na)
    N = cmds.shape[0]
    if cmds.shape != (N, na):
        raise InputError(f"expected (N, {na}) commanded positions, one column per axis {axes}, "
                         f"got shape {cmds.shape}", column="cmds")
    exts = _real(exts, "exts", ncols=m) if m else np.zeros((N, 1))
    if m and exts.shape != (N, m):
        raise InputError(f"expected ({N}, {m}) external input values, one row per command sample "
                         f"and one column per model input, got shape {exts.shape}", column="exts")
    v0 = _real(v0, "v0")
    if v0.shape != (na,):
        raise InputError(f"expected {na} start velocities (mm/s), one per axis {axes}, got shape "
                         f"{v0.shape}", column="v0")
    if not np.isfinite(v0).all():       # as the FMU's <axis>_v0 parameter
        raise InputError(f"start velocities must be finite numbers (mm/s), got "
                         f"{dict(zip(axes, v0.tolist()))}", column="v0")
    st.views["v0"][:] = v0
    Y, U, V = np.empty((N, max(p, 1))), np.empty((N, max(m, 1))), np.empty((N, len(axes)))
    _lib().fdid_run(ct.byref(st.s), N, _dptr(cmds), _dptr(exts), _dptr(Y), _dptr(U), _dptr(V))
    return Y[:, :p], U[:, :m], V


# ------------------------------------------------------------------ the pole search's filter
_INT_MAX = 2 ** 31 - 1      # orders and row counts reach the C as int (ctypes wraps larger ones)


def _c(a):
    return np.ascontiguousarray(a, dtype=float)


def allpole(b0, an, W, zi, R):
    """``R[:, n:] = scipy.signal.lfilter([b0], an, W, zi=zi)`` (``kernel_ext/ls_filter.c``; the
    same doubles). an[0] = 1; W (m, N); zi (m, n); R (m, N + n), C-contiguous, written in place."""
    an, W, zi = _c(an), _real(W, "W"), _c(zi).copy()
    n = an.size - 1
    if not (isinstance(R, np.ndarray) and R.dtype == float and R.flags.c_contiguous
            and R.flags.writeable):
        raise ValueError("allpole: R must be a writeable C-contiguous float64 array (written in place)")
    if not (1 <= n <= _INT_MAX and W.ndim == 2 and W.shape[0] <= _INT_MAX
            and R.shape == (W.shape[0], W.shape[1] + n) and zi.shape == (W.shape[0], n)):
        raise ValueError("allpole: order n >= 1, R C-contiguous floats (m, N + n) and zi (m, n)")
    a0 = float(an.flat[0])
    if np.isfinite(a0) and a0 != 1.0:           # the C never reads an[0] (a NaN passes: NaN out)
        raise ValueError(f"allpole: the denominator must be normalised, an[0] = 1, got {a0!r}")
    # the C reads W and an while it writes R (restrict pointers): a W or an in R's memory (an
    # in-place call) would be read after it was overwritten, so it is copied first
    if np.may_share_memory(W, R):
        W = W.copy()
    if np.may_share_memory(an, R):
        an = an.copy()
    _lib().fdid_allpole(n, float(b0), an.ctypes.data, W.shape[0], W.shape[1], W.ctypes.data,
                        zi.ctypes.data, R.ctypes.data)


def regressor_rows(R, n, inputs, F, start=0, late=None, late_c=None, S=None):
    """Regressor rows ``sum_j F[r, j] R[inputs[r], n - j + k]`` for k >= start, each minus
    ``late_c[r] S[inputs[r], k]`` where ``late[r]`` (``kernel_ext/ls_filter.c``).

    Parameters
    ----------
    R : (m, N + n) all-pole outputs (:func:`~fdid_fmi.identify.regressors.allpole_filter`)
    inputs : (rows,) input index of each row; F : (rows, n + 1) its FIR coefficients
    start : first sample returned (a run-up before it is dropped)
    late, late_c, S : (rows,) flags, (rows,) coefficients, (m, N) signals, optional

    Returns
    -------
    (rows, N - start)
    """
    n, start = operator.index(n), operator.index(start)
    R, F = _real(R, "R"), _real(F, "F")
    # the C takes R as (m, N + n) rows and F as (rows, n + 1): other shapes were reinterpreted
    if not (0 <= n < _INT_MAX and R.ndim == 2 and R.shape[1] >= n and F.ndim in (1, 2)
            and F.shape[-1] == n + 1):
        raise ValueError(f"regressor_rows: R must be (m, N + n) and F (rows, n + 1) with n = {n} >= 0, "
                         f"got R {R.shape} and F {F.shape}")
    m, N = R.shape[0], R.shape[1] - n
    F = F.reshape(-1, n + 1)
    rows = F.shape[0]
    inputs = np.asarray(inputs).reshape(-1)
    # row indices: integers in 0..m-1 (checked before the cast to int, which would wrap or
    # truncate them: 0.7 -> 0, 2**32 -> 0)
    if inputs.shape != (rows,) or rows > _INT_MAX or (rows and (
            inputs.dtype.kind not in "iu" or inputs.min() < 0 or inputs.max() >= m)):
        raise ValueError(f"regressor_rows: inputs must be {rows} integer row indices of R in 0..{m - 1}")
    inputs = np.ascontiguousarray(inputs, dtype=np.intc)
    late = np.zeros(rows, np.intc) if late is None else (np.asarray(late) != 0).astype(np.intc)
    late_c = np.zeros(rows) if late_c is None else _real(late_c, "late_c")
    S = np.zeros((1, 1)) if S is None else _real(S, "S")
    if not 0 <= start <= N or late.shape != (rows,) or late_c.shape != (rows,) \
            or (late.any() and S.shape != (m, N)):
        raise ValueError("regressor_rows: inputs, start, late, late_c or S do not fit R and F")
    out = np.empty((rows, N - start))
    _lib().fdid_regressor_rows(n, N, start, N - start, R.ctypes.data, rows, inputs.ctypes.data,
                               F.ctypes.data, late.ctypes.data, late_c.ctypes.data, S.ctypes.data,
                               out.ctypes.data)
    return out
