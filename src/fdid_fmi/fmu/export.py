"""Export a DriveModel as an FMI Co-Simulation FMU (C backend; pythonfmu as a prototype path).

FMU layout (FMI 2.0)::

    modelDescription.xml
    binaries/linux64/<id>.so        (gcc)
    binaries/win64/<id>.dll         (x86_64-w64-mingw32-gcc, when asked for)
    sources/                        generic C (fdid_core.c, fdid_instance.c, fmi2Functions.c,
                                    fdid_model.h, fdid_instance.h), generated model_data.{h,c},
                                    the FMI headers
    resources/model.json            the DriveModel (used by ``fdid validate`` as the reference)

FMI 3.0 is the same with ``binaries/x86_64-linux``/``x86_64-windows``, ``fmi3Functions.c``
and ``sources/buildDescription.xml``.
"""
from __future__ import annotations

import hashlib
import json
import re
import shutil
import tempfile
import zipfile
from pathlib import Path

from ..errors import FdidError, InputError
from ..model import DriveModel, QuasiStaticModel, check_text, load_model
from ..outputs import atomic_path, check_output
from .build import PLATFORMS, ROOM_ERRNOS, compile_binary, no_room
from .codegen import model_data_c, model_data_h
from .description import build_description_fmi3, model_description_fmi2, model_description_fmi3
from .layout import build_layout, check_exportable


class ExportError(FdidError):
    """The generated FMU failed its own checks (fmpy validation); nothing was written."""

CORE_SOURCES = ("fdid_core.c", "fdid_instance.c")   # written once, compiled into every FMU
HEADERS = ("fdid_model.h", "fdid_instance.h")
FMI_HEADERS = {2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
               3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")}
PLUMBING = {2: "fmi2Functions.c", 3: "fmi3Functions.c"}


def templates_dir():
    """Directory of the C templates: ``fdid_fmi/fmu_templates/``, installed as package data."""
    return Path(__file__).resolve().parents[1] / "fmu_templates"


def model_identifier_for(path):
    """A C identifier from the FMU file name (``my-model.fmu`` -> ``my_model``)."""
    stem = Path(path).name
    if stem.lower().endswith(".fmu"):
        stem = stem[:-4]
    ident = re.sub(r"[^A-Za-z0-9_]", "_", stem) or "fdid_model"
    if not (ident[0].isalpha() or ident[0] == "_"):
        ident = "m_" + ident
    return ident


def fmu_guid(model, fmi_version, model_identifier, backend="c"):
    """GUID (FMI 2) / instantiation token (FMI 3): a hash of the model, the templates, the code
    that numbers the variables and writes the model description (layout.py, description.py), the
    package version and the options."""
    from .. import __version__
    h = hashlib.sha256()
    h.update(json.dumps(model.to_dict(), sort_keys=True).encode())
    h.update(f"|fmi{fmi_version}|{model_identifier}|{backend}|{__version__}|".encode())
    for f in ("layout.py", "description.py"):
        h.update((Path(__file__).parent / f).read_bytes())
    if backend == "c":
        tdir = templates_dir()
        for f in (*CORE_SOURCES, *HEADERS, PLUMBING[fmi_version]):
            h.update((tdir / f).read_bytes())
    d = h.hexdigest()
    return "{" + f"{d[:8]}-{d[8:12]}-{d[12:16]}-{d[16:20]}-{d[20:32]}" + "}"


def export_fmu(model, path, fmi_version=2, platforms=("linux64",), backend="c",
               model_identifier=None, description=None):
    """Export ``model`` as a Co-Simulation FMU.

    Parameters
    ----------
    model : DriveModel, or path of a model JSON file
        Quasi-static models are refused (they have no state-space form).
    path : str or Path
        The ``.fmu`` file to write (its name gives the model identifier unless given).
    fmi_version : 2 or 3
    platforms : sequence of ``linux64`` / ``win64``
        Binaries to compile (C backend). ``sources/`` is always shipped.
    backend : ``c`` (default) or ``python`` (pythonfmu; needs Python + numpy in the importer)
    model_identifier : str, optional
    description : str, optional

    Returns
    -------
    Path of the written FMU. It is written atomically (complete or not at all) and only after
    fmpy's validator (``fmpy.validation.validate_fmu``: schema, names, model structure, units)
    found no problem in it; an existing file at ``path`` is replaced only then.
    """
    inputs = [model] if isinstance(model, (str, Path)) else []
    path = check_output(path, inputs=inputs, what="FMU", suffix=".fmu")
    if isinstance(model, (str, Path)):
        model = load_model(model)
    if isinstance(model, QuasiStaticModel):
        check_exportable(model)
    if not isinstance(model, DriveModel):
        raise InputError(f"expected a DriveModel, got {type(model).__name__}", column="model")
    if description is not None:
        check_text(description, "description", column="description")
    try:
        fmi_version = int(fmi_version)
    except (TypeError, ValueError):
        raise InputError(f"FMI version must be 2 or 3, got {fmi_version!r}", column="fmi") from None
    if fmi_version not in (2, 3):
        raise InputError(f"FMI version must be 2 or 3, got {fmi_version}", column="fmi")
    if isinstance(platforms, str):
        platforms = [p.strip() for p in platforms.split(",") if p.strip()]
    platforms = list(dict.fromkeys(platforms))
    for p in platforms:
        if p not in PLATFORMS:
            raise InputError(f"unknown platform '{p}'; expected one of {sorted(PLATFORMS)}",
                             column="platforms")
    ident = model_identifier or model_identifier_for(path)
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", ident):
        raise InputError(f"model identifier '{ident}' is not a C identifier", column="model_identifier")
    if backend == "python":
        if fmi_version != 2:
            raise InputError("the python backend (pythonfmu) writes FMI 2.0 FMUs only", column="fmi")
        from .python_backend import export_python_fmu
        return export_python_fmu(model, path, model_identifier=ident, description=description)
    if backend != "c":
        raise InputError(f"backend must be 'c' or 'python', got {backend!r}", column="backend")
    layout = build_layout(model)
    guid = fmu_guid(model, fmi_version, ident)
    tdir = templates_dir()
    try:
        tmpdir = tempfile.TemporaryDirectory(prefix="fdid_fmu_")
    except OSError as exc:
        if exc.errno in ROOM_ERRNOS:
            raise no_room(exc.errno, tempfile.gettempdir(), "the FMU's build files") from None
        raise
    with tmpdir as tmp:
        root = Path(tmp) / "fmu"
        try:
            _build_tree(root, model, layout, guid, ident, fmi_version, platforms, description, tdir)
        except OSError as exc:   # a copy's error names the template it read, not the file it wrote
            if exc.errno in ROOM_ERRNOS:
                raise no_room(exc.errno, tempfile.gettempdir(), "the FMU's build files") from None
            raise
        with atomic_path(path) as tmpzip:
            try:
                with zipfile.ZipFile(tmpzip, "w", zipfile.ZIP_DEFLATED) as zf:
                    for f in sorted(root.rglob("*")):
                        if f.is_file():
                            zf.write(f, f.relative_to(root).as_posix())
            except OSError as exc:
                if exc.errno in ROOM_ERRNOS:
                    raise no_room(exc.errno, path.parent, f"the FMU {path.name}") from None
                raise
            check_generated_fmu(tmpzip, path)
    return path


def _build_tree(root, model, layout, guid, ident, fmi_version, platforms, description, tdir):
    """Write the FMU's files into the folder ``root``: sources, compiled binaries, model
    description, ``resources/model.json``."""
    src = root / "sources"
    src.mkdir(parents=True)
    plumbing = PLUMBING[fmi_version]
    sources = [*CORE_SOURCES, plumbing, "model_data.c"]
    for f in (*CORE_SOURCES, plumbing, *HEADERS):
        shutil.copy(tdir / f, src / f)
    for f in FMI_HEADERS[fmi_version]:
        shutil.copy(tdir / "include" / f, src / f)
    (src / "model_data.h").write_text(model_data_h(layout, guid, ident), encoding="ascii")
    (src / "model_data.c").write_text(model_data_c(layout, guid, ident), encoding="ascii")
    for plat in platforms:
        p = PLATFORMS[plat]
        bdir = p.fmi2_dir if fmi_version == 2 else p.fmi3_dir
        compile_binary(src, sources, root / "binaries" / bdir / f"{ident}{p.suffix}", plat,
                       layout.uses_libm)
    if fmi_version == 2:
        xml = model_description_fmi2(layout, guid, ident, description, source_files=sources)
    else:
        xml = model_description_fmi3(layout, guid, ident, description)
        (src / "buildDescription.xml").write_text(build_description_fmi3(ident, sources, layout.uses_libm),
                                                  encoding="utf-8")
    (root / "modelDescription.xml").write_text(xml, encoding="utf-8")
    res = root / "resources"
    res.mkdir()
    # the bytes DriveModel.save writes, written plainly: a temporary folder needs no atomic
    # replace, and a failed write keeps its errno (a full disk is said as such)
    (res / "model.json").write_bytes(json.dumps(model.to_dict(), indent=1).encode("utf-8", "backslashreplace"))


def check_generated_fmu(fmu_file, target):
    """Run fmpy's validator on a freshly built FMU; ExportError listing the problems if any.

    ``fmu_file`` is the (temporary) zip, ``target`` the name it is for (messages)."""
    from fmpy.validation import validate_fmu as fmpy_validate
    problems = fmpy_validate(str(fmu_file))
    if problems:
        raise ExportError(f"{target}: the generated FMU fails fmpy's validation, nothing written: "
                          + "; ".join(str(p) for p in problems[:5]))
