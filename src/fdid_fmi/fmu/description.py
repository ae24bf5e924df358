"""Write ``modelDescription.xml`` (FMI 2.0 and FMI 3.0 Co-Simulation) from an FmuLayout.

Units (mm, mm/s, s, ...) are declared with their SI base units; every variable has a
description, causality, variability and (where FMI wants one) initial/start; the
ModelStructure lists every output with its same-step dependencies on the inputs
(structural, from the feed-through D and the friction loop) and, for FMI 2.0, every output
as an InitialUnknown (dependencies left out: they may depend on every input and parameter).
"""
from __future__ import annotations

import datetime
from xml.sax.saxutils import quoteattr

from .. import __version__
from .layout import FMI_UNITS


def _fmi_unit(u):
    if u is None:
        return None
    return FMI_UNITS[u][0] if u in FMI_UNITS else u


def _log_categories_and_experiment(Ts):
    """<LogCategories> (the categories the C plumbing logs to) and <DefaultExperiment>; the same
    in FMI 2 and FMI 3."""
    return ["  <LogCategories>",
            '    <Category name="logStatusWarning" description="warnings and discarded status requests"/>',
            '    <Category name="logStatusError" description="errors: wrong call order, bad step size, '
            'unknown value reference, non-finite value (logged unless switched off)"/>',
            '    <Category name="logStatusFatal" description="fatal errors (out of memory)"/>',
            '    <Category name="logCalls" description="trace of every FMI call"/>',
            "  </LogCategories>",
            f'  <DefaultExperiment startTime="0.0" stepSize="{Ts!r}"/>']


def _unit_definitions(layout):
    used = []
    for v in layout.variables:
        if v.unit and v.unit not in used:
            used.append(v.unit)
    if "s" not in used:
        used.append("s")
    out = ["  <UnitDefinitions>"]
    for u in used:
        name, base, factor = FMI_UNITS.get(u, (u, {}, 1.0))
        if base:
            attrs = "".join(f' {k}="{e}"' for k, e in base.items())
            fac = f' factor="{factor!r}"' if factor != 1.0 else ""
            out.append(f"    <Unit name={quoteattr(name)}><BaseUnit{attrs}{fac}/></Unit>")
        else:
            out.append(f"    <Unit name={quoteattr(name)}/>")
    out.append("  </UnitDefinitions>")
    return out


def _fmt(x):
    if isinstance(x, bool):
        return "true" if x else "false"
    return repr(float(x))


def _header(layout, guid, model_identifier, description):
    m = layout.model
    desc = description or (f"fdid-fmi feed-drive model ({m.method or 'state space'}; axes "
                           f"{', '.join(layout.axes)}; {m.n_states} states; Ts = {m.Ts!r} s)")
    return desc, datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def model_description_fmi2(layout, guid, model_identifier, description=None, source_files=()):
    """Text of an FMI 2.0 Co-Simulation modelDescription.xml."""
    m = layout.model
    desc, stamp = _header(layout, guid, model_identifier, description)
    L = ['<?xml version="1.0" encoding="UTF-8"?>',
         '<fmiModelDescription fmiVersion="2.0"',
         f"  modelName={quoteattr(model_identifier)}",
         f"  guid={quoteattr(guid)}",
         f"  description={quoteattr(desc)}",
         f'  generationTool="fdid-fmi {__version__}"',
         f'  generationDateAndTime="{stamp}"',
         '  variableNamingConvention="flat"',
         '  numberOfEventIndicators="0">',
         f'  <CoSimulation modelIdentifier={quoteattr(model_identifier)}',
         '    canHandleVariableCommunicationStepSize="true"',
         '    canInterpolateInputs="false"',
         '    maxOutputDerivativeOrder="0"',
         '    canRunAsynchronuously="false"',
         '    canBeInstantiatedOnlyOncePerProcess="false"',
         '    canNotUseMemoryManagementFunctions="false"',
         '    canGetAndSetFMUstate="true"',
         '    canSerializeFMUstate="true"',
         '    providesDirectionalDerivative="false">']
    if source_files:
        L.append("    <SourceFiles>")
        L += [f"      <File name={quoteattr(f)}/>" for f in source_files]
        L.append("    </SourceFiles>")
    L.append("  </CoSimulation>")
    L += _unit_definitions(layout)
    L += _log_categories_and_experiment(m.Ts) + ["  <ModelVariables>"]
    index = {}
    for k, v in enumerate(layout.variables, start=1):
        index[v.name] = k
        attrs = [f"name={quoteattr(v.name)}", f'valueReference="{v.vr}"',
                 f"description={quoteattr(v.description)}", f'causality="{v.causality}"',
                 f'variability="{v.variability}"']
        if v.initial and v.causality != "input":
            attrs.append(f'initial="{v.initial}"')
        tattrs = []
        if v.type == "Real" and v.unit:
            tattrs.append(f"unit={quoteattr(_fmi_unit(v.unit))}")
        if v.role == "level":
            tattrs.append('min="0.0"')
        if v.start is not None:
            tattrs.append(f'start="{_fmt(v.start)}"')
        L.append(f"    <!-- {k} --><ScalarVariable {' '.join(attrs)}>")
        L.append(f"      <{v.type}{''.join(' ' + t for t in tattrs)}/>")
        L.append("    </ScalarVariable>")
    L.append("  </ModelVariables>")
    L.append("  <ModelStructure>")
    L.append("    <Outputs>")
    for v in layout.outputs:
        dep = " ".join(str(index[d]) for d in v.depends)
        kinds = " ".join("dependent" for _ in v.depends)
        L.append(f'      <Unknown index="{index[v.name]}" dependencies="{dep}" dependenciesKind="{kinds}"/>')
    L.append("    </Outputs>")
    L.append("    <InitialUnknowns>")
    for v in layout.outputs:
        L.append(f'      <Unknown index="{index[v.name]}"/>')
    L.append("    </InitialUnknowns>")
    L.append("  </ModelStructure>")
    L.append("</fmiModelDescription>")
    return "\n".join(L) + "\n"


def model_description_fmi3(layout, guid, model_identifier, description=None):
    """Text of an FMI 3.0 Co-Simulation modelDescription.xml (Float64 / Boolean variables)."""
    m = layout.model
    desc, stamp = _header(layout, guid, model_identifier, description)
    L = ['<?xml version="1.0" encoding="UTF-8"?>',
         '<fmiModelDescription fmiVersion="3.0"',
         f"  modelName={quoteattr(model_identifier)}",
         f"  instantiationToken={quoteattr(guid)}",
         f"  description={quoteattr(desc)}",
         f'  generationTool="fdid-fmi {__version__}"',
         f'  generationDateAndTime="{stamp}"',
         '  variableNamingConvention="flat">',
         f'  <CoSimulation modelIdentifier={quoteattr(model_identifier)}',
         '    canHandleVariableCommunicationStepSize="true"',
         '    canGetAndSetFMUState="true"',
         '    canSerializeFMUState="true"',
         '    providesDirectionalDerivatives="false"',
         '    providesAdjointDerivatives="false"',
         '    providesIntermediateUpdate="false"',
         '    canReturnEarlyAfterIntermediateUpdate="false"',
         f'    fixedInternalStepSize="{m.Ts!r}"',
         '    hasEventMode="false"/>']
    L += _unit_definitions(layout)
    L += _log_categories_and_experiment(m.Ts) + [
          "  <ModelVariables>",
          '    <Float64 name="time" valueReference="999999" causality="independent" '
          'variability="continuous" description="simulation time" unit="s"/>']
    for v in layout.variables:
        tag = "Float64" if v.type == "Real" else "Boolean"
        attrs = [f"name={quoteattr(v.name)}", f'valueReference="{v.vr}"',
                 f"description={quoteattr(v.description)}", f'causality="{v.causality}"',
                 f'variability="{v.variability}"']
        if v.initial and v.causality != "input":
            attrs.append(f'initial="{v.initial}"')
        if v.type == "Real" and v.unit:
            attrs.append(f"unit={quoteattr(_fmi_unit(v.unit))}")
        if v.role == "level":
            attrs.append('min="0.0"')
        if v.start is not None:
            attrs.append(f'start="{_fmt(v.start)}"')
        L.append(f"    <{tag} {' '.join(attrs)}/>")
    L.append("  </ModelVariables>")
    L.append("  <ModelStructure>")
    for v in layout.outputs:
        deps = " ".join(str(layout.vr(d)) for d in v.depends)
        kinds = " ".join("dependent" for _ in v.depends)
        L.append(f'    <Output valueReference="{v.vr}" dependencies="{deps}" dependenciesKind="{kinds}"/>')
    for v in layout.outputs:
        L.append(f'    <InitialUnknown valueReference="{v.vr}"/>')
    L.append("  </ModelStructure>")
    L.append("</fmiModelDescription>")
    return "\n".join(L) + "\n"
