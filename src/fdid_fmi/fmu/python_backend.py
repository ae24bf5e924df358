"""pythonfmu backend (``fdid export --backend python``): a prototyping path, never the default.

The FMU carries ``resources/<module>.py`` (the slave, from ``python_slave_template.py``) and
``resources/fdid_layout.json`` (model data + variable table) and pythonfmu's generic binary,
which starts the Python interpreter it finds at run time. So the importer needs Python 3 with
fdid-fmi installed (its compiled simulation core steps the model) and a libpython that
pythonfmu can load. The
modelDescription.xml is the same as the C backend's (units, ModelStructure), with pythonfmu's
CoSimulation capabilities. FMI 2.0 only.
"""
from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

from ..errors import InputError
from .description import model_description_fmi2
from .export import check_generated_fmu, fmu_guid
from .layout import build_layout


def layout_json(layout, guid, ident, description=None):
    """The data the Python slave needs, as a JSON-able dict: the model and the variable table."""
    return {"model": layout.model.to_dict(),
            "variables": [{"name": v.name, "role": v.role, "index": v.index, "type": v.type, "vr": v.vr,
                           "causality": v.causality, "variability": v.variability,
                           "description": v.description} for v in layout.variables],
            "model_description": model_description_fmi2(layout, guid, ident, description)}


def export_python_fmu(model, path, model_identifier, description=None):
    """Build a pythonfmu FMU of ``model`` at ``path`` (see module docstring)."""
    try:
        from pythonfmu.builder import FmuBuilder
    except ImportError:
        raise InputError("the python backend needs pythonfmu (pip install pythonfmu)",
                         column="backend") from None
    layout = build_layout(model)
    guid = fmu_guid(model, 2, model_identifier, backend="python")
    template = (Path(__file__).with_name("python_slave_template.py")).read_text()
    code = template.replace("__CLASS_NAME__", model_identifier)
    # a module name unique per model: pythonfmu imports the script by name
    module = f"fdid_slave_{guid.strip('{}').replace('-', '')[:16]}"
    path = Path(path)
    with tempfile.TemporaryDirectory(prefix="fdid_pyfmu_") as tmp:
        tmp = Path(tmp)
        script = tmp / f"{module}.py"
        script.write_text(code)
        data = tmp / "data"
        data.mkdir()
        (data / "fdid_layout.json").write_text(json.dumps(layout_json(layout, guid, model_identifier,
                                                                      description)))
        out = tmp / "out"
        out.mkdir()
        built = FmuBuilder.build_FMU(script, dest=out / f"{model_identifier}.fmu",
                                     project_files=[data / "fdid_layout.json"])
        check_generated_fmu(built, str(path))     # as export_fmu promises: nothing invalid written
        from ..outputs import atomic_path
        with atomic_path(path) as tmpfmu:
            shutil.copyfile(str(built), str(tmpfmu))
    return path
