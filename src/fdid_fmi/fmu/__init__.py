"""FMU export (C templates in ``fmu_templates/``; pythonfmu prototype backend) and validation.

``export_fmu(model, path, fmi_version=2, platforms=("linux64",), backend="c") -> Path``
``validate_fmu(fmu_path, trace, model=None) -> ValidationResult``
"""
from .export import export_fmu, fmu_guid, model_identifier_for, templates_dir
from .layout import FmuLayout, build_layout


def __getattr__(name):
    if name in ("validate_fmu", "ValidationResult", "run_fmu"):
        from . import validate
        return getattr(validate, name)
    raise AttributeError(name)


__all__ = ["export_fmu", "validate_fmu", "ValidationResult", "run_fmu", "build_layout", "FmuLayout",
           "fmu_guid", "model_identifier_for", "templates_dir"]
