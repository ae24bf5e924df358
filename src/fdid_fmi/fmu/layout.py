"""The FMU's view of a DriveModel: variables, value references, port indices, dependencies.

Computed once per model and shared by the C code generator, the modelDescription.xml writer,
the pythonfmu backend and the validation driver, so that all of them agree on names and
value references.

Variables (value reference = FIRST_VR + position in :attr:`FmuLayout.variables`):

===========================  ==========  =========  ==========================================
name                         causality   unit       meaning
===========================  ==========  =========  ==========================================
``<axis>_x_cmd``             input       mm         commanded position x_r
``<external input name>``    input       port unit  identified extra input (e.g. a force)
``<axis>_x``                 output      mm         predicted position x
``<axis>_v``                 output      mm/s       velocity (model output or backward diff.)
``<axis>_x_tool``            output      mm         tool-side position (flexible-mode models)
``<other output name>``      output      port unit  any other model output
``<friction/feature name>``  local       1          applied friction / feature input value
``<axis>_friction_level``    parameter   1          friction level L (tunable)
``<axis>_v_tilde``           parameter   mm/s       friction transition velocity (tunable)
``<axis>_friction_on``       parameter   Boolean    friction on/off (tunable)
``<axis>_v0``                parameter   mm/s       start velocity (fixed; 0 = at rest)
===========================  ==========  =========  ==========================================

No tracking-error output: read after ``doStep(t_k, h)`` the outputs are the prediction for
t_k + h, while the FMU still holds the command of t_k, so x_cmd - x there would be neither
instant's error. A master computes the tracking error at its time t as x_cmd(t) - ``<axis>_x``(t).
A model output of kind ``error`` is not exported for the same reason (:attr:`FmuLayout.axis_err`
keeps its index for the reference simulator).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..model import (FEATURE_FUNCTIONS, LIBM_FUNCTIONS, DriveModel, QuasiStaticModel, delayed_input,
                     vtilde_floor_per_level)

# FMI unit name and base-unit exponents/factor (to SI) for the canonical units of fdid_fmi.units
FMI_UNITS = {
    "mm": ("mm", {"m": 1}, 1e-3),
    "mm_s": ("mm/s", {"m": 1, "s": -1}, 1e-3),
    "mm_s2": ("mm/s2", {"m": 1, "s": -2}, 1e-3),
    "mm_s3": ("mm/s3", {"m": 1, "s": -3}, 1e-3),
    "s": ("s", {"s": 1}, 1.0),
    "deg": ("deg", {"rad": 1}, 0.017453292519943295),
    "deg_s": ("deg/s", {"rad": 1, "s": -1}, 0.017453292519943295),
    "A": ("A", {"A": 1}, 1.0),
    "V": ("V", {"kg": 1, "m": 2, "s": -3, "A": -1}, 1.0),
    "N": ("N", {"kg": 1, "m": 1, "s": -2}, 1.0),
    "Nm": ("N.m", {"kg": 1, "m": 2, "s": -2}, 1.0),
}
VELOCITY_UNIT = {"mm": "mm_s", "deg": "deg_s"}

# roles (must match the enum in fmu_templates/fdid_model.h)
ROLES = ("cmd", "ext", "pos", "vel", "tool", "y", "u", "level", "v_tilde", "on", "v0")
FEATURES = FEATURE_FUNCTIONS      # the enum FDID_F_* in fmu_templates/fdid_model.h, in this order
KINDS = ("command", "external", "friction", "feature")
# value reference of the first variable; the others follow in the order of FmuLayout.variables
# (the C lookup, fdid_instance.c, reads it from model_data.h). Not 0: some masters read FMI 3
# dependencies (value references) as 1-based variable indices.
FIRST_VR = 1


@dataclass
class FmuVariable:
    """One FMI scalar variable."""

    name: str
    role: str                 # one of ROLES
    index: int                # axis index or model port index (see fdid_model.h)
    causality: str            # input / output / local / parameter
    variability: str          # continuous / tunable / fixed
    type: str = "Real"        # Real / Boolean
    unit: str | None = None   # canonical fdid unit (``mm``, ``mm_s``...) or None
    start: float | None = None
    description: str = ""
    initial: str | None = None
    depends: list = field(default_factory=list)   # names of inputs an output depends on
    vr: int = -1


@dataclass
class FmuLayout:
    """Everything the FMU generators need to know about a model."""

    model: DriveModel
    axes: list
    variables: list
    fric_inputs: list         # model input indices
    fric_vel_output: list     # output index of the velocity source of each friction input
    fric_vel_diff: list       # 1 if that source is a position (backward difference)
    axis_cmd: list
    axis_pos: list
    axis_err: list            # model error output per axis, -1 if none (not an FMU variable)
    axis_vel: list
    axis_tool: list
    axis_level0: list
    axis_vtilde0: list
    axis_vtilde_floor: list   # least v_tilde per unit level (model.vtilde_floor_per_level)
    uses_libm: bool

    def by_name(self, name):
        for v in self.variables:
            if v.name == name:
                return v
        raise KeyError(name)

    def vr(self, name):
        return self.by_name(name).vr

    @property
    def inputs(self):
        return [v for v in self.variables if v.causality == "input"]

    @property
    def outputs(self):
        return [v for v in self.variables if v.causality == "output"]

    @property
    def parameters(self):
        return [v for v in self.variables if v.causality == "parameter"]


def check_exportable(model):
    """Raise InputError when ``model`` cannot become an FMU (quasi-static, unsupported data)."""
    if isinstance(model, QuasiStaticModel):
        raise InputError("quasi-static models (Eqn 3.3-3.4) have no state-space form and cannot be "
                         "exported as an FMU; identify a pole-search or MIMO model instead",
                         column="model")
    if not isinstance(model, DriveModel):
        raise InputError(f"expected a DriveModel, got {type(model).__name__}", column="model")
    model.validate()
    for p in model.inputs:
        if p.kind == "feature" and p.axis not in model.axes:
            raise InputError("a feature input needs the axis whose velocity/position it uses",
                             column=p.name)
    fr = [p for p in model.inputs if p.kind == "friction"]
    if len(fr) > 4:
        raise InputError("at most 4 friction inputs are supported", column="friction")
    for p in fr:
        lev = float(p.params.get("level", 1.0))
        if not (np.isfinite(lev) and lev >= 0):
            raise InputError(f"friction level must be a finite number >= 0, got {float(lev)!r}", column=p.name)
    for ax in model.axes:
        ps = [p for p in fr if p.axis == ax]
        if len({(float(p.params.get("level", 1.0)), float(p.params["v_tilde"])) for p in ps}) > 1:
            raise InputError(f"axis '{ax}' has several friction inputs with different level/v_tilde; "
                             f"the FMU exposes one friction_level/v_tilde parameter per axis",
                             column=ax)


def build_layout(model):
    """Compute the :class:`FmuLayout` of a DriveModel (raises InputError when not exportable)."""
    check_exportable(model)
    m = model
    axes = list(m.axes)
    ins, outs = m.inputs, m.outputs
    cmd = [m.input_index("command", a) for a in axes]
    pos = [m.output_index("position", a) for a in axes]
    err = [_or(m.output_index("error", a)) for a in axes]
    vel = [_or(m.output_index("velocity", a)) for a in axes]
    tool = [_or(m.output_index("tool_position", a)) for a in axes]
    fric = [i for i, p in enumerate(ins) if p.kind == "friction"]
    sources = [m.friction_velocity_source(i) for i in fric]
    fvo, fvd = [o for o, _ in sources], [int(d) for _, d in sources]
    level0, vt0, floor = [], [], []
    floors = vtilde_floor_per_level(m)
    for a in axes:
        ps = [ins[i] for i in fric if ins[i].axis == a]
        level0.append(float(ps[0].params.get("level", 1.0)) if ps else 0.0)
        vt0.append(float(ps[0].params["v_tilde"]) if ps else 1.0)
        floor.append(max([floors[i] for i in fric if ins[i].axis == a and i in floors], default=0.0))
    uses_libm = any(p.kind == "feature" and p.params.get("function") in LIBM_FUNCTIONS for p in ins)

    deps = _dependencies(m, axes, cmd, pos, vel, fric, fvo)

    names = {"time"}        # the FMI 3 independent variable (fmu/description.py) takes that name

    def unique(name, prefix):
        while name in names:
            name = prefix + name
        names.add(name)
        return name

    V = []
    for k, a in enumerate(axes):
        u = ins[cmd[k]].unit or "mm"
        V.append(FmuVariable(unique(f"{a}_x_cmd", "u_"), "cmd", k, "input", "continuous", unit=u,
                             start=0.0, description=f"commanded position of axis {a}"))
    for i, p in enumerate(ins):
        if p.kind == "external":
            V.append(FmuVariable(unique(p.name, "u_"), "ext", i, "input", "continuous",
                                 unit=_unit(p.unit), start=0.0,
                                 description=p.description or f"external input {p.name}"))
    in_name = {("cmd", k): V[k].name for k in range(len(axes))}
    for v in V:
        if v.role == "ext":
            in_name[("ext", v.index)] = v.name
    covered = set()
    for k, a in enumerate(axes):
        u = ins[cmd[k]].unit or "mm"
        vu = VELOCITY_UNIT.get(u, None)
        V.append(FmuVariable(unique(f"{a}_x", "y_"), "pos", k, "output", "continuous", unit=u,
                             description=f"predicted position of axis {a}",
                             depends=deps["out"][pos[k]]))
        covered.add(pos[k])
        if err[k] >= 0:     # not exported: x_cmd - x of the held command (see the module notes)
            covered.add(err[k])
        v_dep = deps["out"][vel[k]] if vel[k] >= 0 else deps["out"][pos[k]]
        V.append(FmuVariable(unique(f"{a}_v", "y_"), "vel", k, "output", "continuous", unit=vu,
                             description=f"velocity of axis {a}" + (
                                 "" if vel[k] >= 0 else " (backward difference of the position)"),
                             depends=v_dep))
        if vel[k] >= 0:
            covered.add(vel[k])
        if tool[k] >= 0:
            V.append(FmuVariable(unique(f"{a}_x_tool", "y_"), "tool", k, "output", "continuous", unit=u,
                                 description=f"tool-side position of axis {a}",
                                 depends=deps["out"][tool[k]]))
            covered.add(tool[k])
    for o, p in enumerate(outs):
        if o not in covered:
            V.append(FmuVariable(unique(p.name, "y_"), "y", o, "output", "continuous", unit=_unit(p.unit),
                                 description=p.description or f"model output {p.name} ({p.kind})",
                                 depends=deps["out"][o]))
    for i, p in enumerate(ins):
        if p.kind in ("friction", "feature"):
            what = ("normalised Coulomb friction input d_nf = L sat(v / v_tilde)" if p.kind == "friction"
                    else f"feature input {p.params.get('function')}")
            V.append(FmuVariable(unique(p.name, "d_"), "u", i, "local", "continuous", unit=None,
                                 initial="calculated",
                                 description=f"applied {what} of axis {p.axis}"))
    for k, a in enumerate(axes):
        if any(ins[i].axis == a for i in fric):
            V.append(FmuVariable(unique(f"{a}_friction_level", "p_"), "level", k, "parameter", "tunable",
                                 start=level0[k], initial="exact",
                                 description=f"friction level L of axis {a} (scales d_nf; >= 0)"))
            V.append(FmuVariable(unique(f"{a}_v_tilde", "p_"), "v_tilde", k, "parameter", "tunable",
                                 unit=VELOCITY_UNIT.get(ins[cmd[k]].unit or "mm", "mm_s"),
                                 start=vt0[k], initial="exact",
                                 description=f"friction transition velocity v_tilde of axis {a} (> 0"
                                             + (f"; at least {floor[k]:.3g} x the friction level" if floor[k] else "")
                                             + ")"))
            V.append(FmuVariable(unique(f"{a}_friction_on", "p_"), "on", k, "parameter", "tunable",
                                 type="Boolean", start=True, initial="exact",
                                 description=f"friction of axis {a} on (true) or off (false)"))
    for k, a in enumerate(axes):
        V.append(FmuVariable(unique(f"{a}_v0", "p_"), "v0", k, "parameter", "fixed",
                             unit=VELOCITY_UNIT.get(ins[cmd[k]].unit or "mm", "mm_s"), start=0.0,
                             initial="exact",
                             description=f"start velocity of axis {a}: the model starts in the steady "
                                         f"state of a ramp at this velocity (0 = at rest)"))
    for vr, v in enumerate(V, start=FIRST_VR):
        v.vr = vr
        v.depends = [in_name[d] for d in v.depends]
    return FmuLayout(model=m, axes=axes, variables=V, fric_inputs=fric, fric_vel_output=fvo,
                     fric_vel_diff=fvd, axis_cmd=cmd, axis_pos=pos, axis_err=err, axis_vel=vel,
                     axis_tool=tool, axis_level0=level0, axis_vtilde0=vt0,
                     axis_vtilde_floor=floor, uses_libm=uses_libm)


def sparse_rows(X):
    """The nonzero entries of X by row (the C core's ``FdidRows``: compressed sparse rows, the
    columns ascending within a row; NaN counts as nonzero).

    Returns
    -------
    start : (r + 1,) int, row i holds entries start[i] .. start[i + 1] - 1
    col : (nnz,) int, their columns
    val : (nnz,) float, their values
    """
    X = np.asarray(X, dtype=float)
    rows, cols = np.nonzero(X)             # row-major: columns ascend within each row
    start = np.zeros(X.shape[0] + 1, dtype=np.intc)
    np.cumsum(np.bincount(rows, minlength=X.shape[0]), out=start[1:])
    return start, cols.astype(np.intc), X[rows, cols]


def step_rows(model):
    """[A B] and [C D] of a DriveModel as :func:`sparse_rows` (the C core's step matrices,
    acting on z = [xi; u])."""
    return (sparse_rows(np.hstack([model.A, model.B])),
            sparse_rows(np.hstack([model.C, model.D])))


def _or(i):
    return -1 if i is None else i


def _unit(u):
    return None if u in (None, "", "1") else u


def _dependencies(m, axes, cmd, pos, vel, fric, fvo):
    """Same-step dependencies of every model output on the FMU inputs (structural, from D).

    An output depends on an input when D couples them directly, through a feature input
    computed from the current command (sin/cos_position of the command), or through the
    friction inputs, whose exact solve makes them depend on everything their velocity
    sources depend on.
    """
    ins = m.inputs
    aidx = {a: i for i, a in enumerate(axes)}
    direct = {}   # model input index -> set of FMU input keys it carries at the same step
    for i, p in enumerate(ins):
        if not delayed_input(p.kind, p.params):     # friction, velocity/position features
            direct[i] = set()
        elif p.kind == "external":
            direct[i] = {("ext", i)}
        else:                                       # the command, or a feature of it
            direct[i] = {("cmd", aidx[p.axis])}

    def lin(o):
        s = set()
        for i in range(len(ins)):
            if i not in fric and m.D[o, i] != 0.0:
                s |= direct[i]
        return s

    fdep = set()
    for o in fvo:
        fdep |= lin(o)
    out = {}
    for o in range(m.D.shape[0]):
        s = lin(o)
        if any(m.D[o, i] != 0.0 for i in fric):
            s |= fdep
        out[o] = sorted(s)
    out[-1] = []
    return {"out": out}
