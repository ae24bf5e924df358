"""Write ``modelDescription.xml`` (FMI 2.0 and FMI 3.0 Co-Simulation) from an FmuLayout.

Units (mm, mm/s, s, ...) are declared with their SI base units; every variable has a
description, causality, variability and (where FMI wants one) initial/start; the
ModelStructure lists every output with its same-step dependencies on the inputs
(structural, from the feed-through D and the friction loop) and, for FMI 2.0, every output
as an InitialUnknown (dependencies left out: they may depend on every input and parameter).

The XML is built with :mod:`xml.etree.ElementTree` (never by pasting strings), so names,
units and descriptions from a model file are escaped by the library; every attribute value
is also checked to hold only characters XML 1.0 allows (:func:`xml_text`), and the result is
parsed back before it is returned. Names themselves are checked by
:meth:`fdid_fmi.model.DriveModel.validate` (identifiers, printable text).
"""
from __future__ import annotations

import datetime
import xml.etree.ElementTree as ET

from .. import __version__
from ..errors import InputError
from .layout import FMI_UNITS


def xml_text(value, what="text"):
    """``str(value)`` when every character is allowed in XML 1.0 (and is not a noncharacter),
    else InputError naming ``what``."""
    s = str(value)
    for k, ch in enumerate(s):
        o = ord(ch)
        if not (o in (0x9, 0xA, 0xD) or 0x20 <= o <= 0xD7FF or 0xE000 <= o <= 0xFFFD
                or 0x10000 <= o <= 0x10FFFF) or 0xFDD0 <= o <= 0xFDEF:
            raise InputError(f"{what} has the character U+{o:04X} at position {k + 1}, which "
                             f"modelDescription.xml cannot hold", column=what)
    return s


def _el(parent, tag, attrs=(), what=None):
    """Sub-element with attributes in the given order (None values left out), each checked."""
    e = ET.SubElement(parent, tag) if parent is not None else ET.Element(tag)
    for k, v in (attrs.items() if isinstance(attrs, dict) else attrs):
        if v is not None:
            e.set(k, xml_text(v, what or f"{tag}.{k}"))
    return e


def _serialise(root):
    """Text of the document (UTF-8 declaration, two-space indent), parsed back as a check."""
    ET.indent(root, space="  ")
    text = '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
    ET.fromstring(text.encode("utf-8"))   # well-formed, or ParseError (a bug: inputs are checked)
    return text


def _fmi_unit(u):
    if u is None:
        return None
    return FMI_UNITS[u][0] if u in FMI_UNITS else u


def _log_categories_and_experiment(root, Ts):
    """<LogCategories> (the categories the C plumbing logs to) and <DefaultExperiment>; the same
    in FMI 2 and FMI 3."""
    cats = _el(root, "LogCategories")
    for name, desc in (
            ("logStatusWarning", "warnings and discarded status requests"),
            ("logStatusError", "errors: wrong call order, bad step size, unknown value reference, "
                               "non-finite value (logged unless switched off)"),
            ("logStatusFatal", "fatal errors (out of memory)"),
            ("logCalls", "trace of every FMI call")):
        _el(cats, "Category", {"name": name, "description": desc})
    _el(root, "DefaultExperiment", {"startTime": "0.0", "stepSize": repr(float(Ts))})


def _unit_definitions(root, layout):
    used = []
    for v in layout.variables:
        if v.unit and v.unit not in used:
            used.append(v.unit)
    if "s" not in used:
        used.append("s")
    defs = _el(root, "UnitDefinitions")
    for u in used:
        name, base, factor = FMI_UNITS.get(u, (u, {}, 1.0))
        unit = _el(defs, "Unit", {"name": name}, what="unit")
        if base:
            attrs = {k: str(e) for k, e in base.items()}
            if factor != 1.0:
                attrs["factor"] = repr(float(factor))
            _el(unit, "BaseUnit", attrs)


def _fmt(x):
    if isinstance(x, bool):
        return "true" if x else "false"
    return repr(float(x))


def _header(layout, guid, model_identifier, description):
    m = layout.model
    desc = description or (f"fdid-fmi feed-drive model ({m.method or 'state space'}; axes "
                           f"{', '.join(layout.axes)}; {m.n_states} states; Ts = {float(m.Ts)!r} s)")
    return desc, datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def _variable_attrs(v):
    attrs = {"name": v.name, "valueReference": str(v.vr), "description": v.description,
             "causality": v.causality, "variability": v.variability}
    if v.initial and v.causality != "input":
        attrs["initial"] = v.initial
    return attrs


def model_description_fmi2(layout, guid, model_identifier, description=None, source_files=()):
    """Text of an FMI 2.0 Co-Simulation modelDescription.xml."""
    m = layout.model
    desc, stamp = _header(layout, guid, model_identifier, description)
    root = _el(None, "fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": model_identifier, "guid": guid, "description": desc,
        "generationTool": f"fdid-fmi {__version__}", "generationDateAndTime": stamp,
        "variableNamingConvention": "flat", "numberOfEventIndicators": "0"}, what="description")
    cs = _el(root, "CoSimulation", {
        "modelIdentifier": model_identifier, "canHandleVariableCommunicationStepSize": "false",
        "canInterpolateInputs": "true", "maxOutputDerivativeOrder": "0",
        "canRunAsynchronuously": "false", "canBeInstantiatedOnlyOncePerProcess": "false",
        "canNotUseMemoryManagementFunctions": "false", "canGetAndSetFMUstate": "true",
        "canSerializeFMUstate": "true", "providesDirectionalDerivative": "false"})
    if source_files:
        sf = _el(cs, "SourceFiles")
        for f in source_files:
            _el(sf, "File", {"name": f})
    _unit_definitions(root, layout)
    _log_categories_and_experiment(root, m.Ts)
    mv = _el(root, "ModelVariables")
    index = {}
    for k, v in enumerate(layout.variables, start=1):
        index[v.name] = k
        mv.append(ET.Comment(f" {k} "))
        sv = _el(mv, "ScalarVariable", _variable_attrs(v), what=f"variable {v.name!r}")
        tattrs = {}
        if v.type == "Real" and v.unit:
            tattrs["unit"] = _fmi_unit(v.unit)
        if v.role == "level":
            tattrs["min"] = "0.0"
        if v.start is not None:
            tattrs["start"] = _fmt(v.start)
        _el(sv, v.type, tattrs, what=f"unit of {v.name!r}")
    ms = _el(root, "ModelStructure")
    outs = _el(ms, "Outputs")
    for v in layout.outputs:
        _el(outs, "Unknown", {"index": str(index[v.name]),
                              "dependencies": " ".join(str(index[d]) for d in v.depends),
                              "dependenciesKind": " ".join("dependent" for _ in v.depends)})
    iu = _el(ms, "InitialUnknowns")
    for v in layout.outputs:
        _el(iu, "Unknown", {"index": str(index[v.name])})
    return _serialise(root)


def model_description_fmi3(layout, guid, model_identifier, description=None):
    """Text of an FMI 3.0 Co-Simulation modelDescription.xml (Float64 / Boolean variables)."""
    m = layout.model
    desc, stamp = _header(layout, guid, model_identifier, description)
    root = _el(None, "fmiModelDescription", {
        "fmiVersion": "3.0", "modelName": model_identifier, "instantiationToken": guid,
        "description": desc, "generationTool": f"fdid-fmi {__version__}",
        "generationDateAndTime": stamp, "variableNamingConvention": "flat"}, what="description")
    _el(root, "CoSimulation", {
        "modelIdentifier": model_identifier, "canHandleVariableCommunicationStepSize": "false",
        "canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
        "providesDirectionalDerivatives": "false", "providesAdjointDerivatives": "false",
        "providesIntermediateUpdate": "true", "canReturnEarlyAfterIntermediateUpdate": "false",
        "fixedInternalStepSize": repr(float(m.Ts)), "hasEventMode": "false"})
    _unit_definitions(root, layout)
    _log_categories_and_experiment(root, m.Ts)
    mv = _el(root, "ModelVariables")
    for v in layout.variables:
        attrs = _variable_attrs(v)
        if v.type == "Real" and v.unit:
            attrs["unit"] = _fmi_unit(v.unit)
        if v.role == "level":
            attrs["min"] = "0.0"
        if v.start is not None:
            attrs["start"] = _fmt(v.start)
        if v.causality == "input":
            # settable in intermediate update mode: the inputs of each sample of a coarse step
            attrs["intermediateUpdate"] = "true"
        _el(mv, "Float64" if v.type == "Real" else "Boolean", attrs, what=f"variable {v.name!r}")
    # the independent variable last: the variable with value reference k (from FIRST_VR = 1) is
    # then also the k-th in the list, so a master that reads dependencies as 1-based indices
    # names the same variable as the standard's reading (value references)
    _el(mv, "Float64", {"name": "time", "valueReference": "999999", "causality": "independent",
                        "variability": "continuous", "description": "simulation time", "unit": "s"})
    ms = _el(root, "ModelStructure")
    for v in layout.outputs:
        _el(ms, "Output", {"valueReference": str(v.vr),
                           "dependencies": " ".join(str(layout.vr(d)) for d in v.depends),
                           "dependenciesKind": " ".join("dependent" for _ in v.depends)})
    for v in layout.outputs:
        _el(ms, "InitialUnknown", {"valueReference": str(v.vr)})
    return _serialise(root)


def build_description_fmi3(model_identifier, sources, uses_libm):
    """Text of the FMI 3.0 ``sources/buildDescription.xml``."""
    root = _el(None, "fmiBuildDescription", {"fmiVersion": "3.0"})
    bc = _el(root, "BuildConfiguration", {"modelIdentifier": model_identifier,
                                          "description": "C99; link -lm only if listed"})
    sfs = _el(bc, "SourceFileSet", {"language": "C99"})
    for s in sources:
        _el(sfs, "SourceFile", {"name": s})
    if uses_libm:
        _el(bc, "Library", {"name": "m"})
    return _serialise(root)
