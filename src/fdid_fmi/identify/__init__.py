"""Identification methods (thesis ch. 3, 4, 5).

- :func:`identify_quasi_static` (ch. 3) -> QuasiStaticModel
- :func:`identify_full_ls` (section 4.2, the baseline) -> DriveModel
- :func:`identify_siso` (section 4.3, pole search with LS projection) -> DriveModel
- :func:`identify_mimo` (ch. 5, scaled MIMO LTI pole search) -> DriveModel
- :func:`identify_auto` (the pole search with the structure chosen from the data) -> DriveModel
"""
from .choose_structure import StructureChoice, identify_auto
from .full_ls import identify_full_ls
from .pole_search import identify_mimo, identify_siso
from .quasi_static import feed_limits, identify_quasi_static
from .structure import Bounds, InputSpec, OutputSpec, Structure, default_bounds, mimo_structure, siso_structure

__all__ = ["identify_auto", "StructureChoice", "identify_quasi_static", "identify_full_ls", "identify_siso", "identify_mimo", "feed_limits",
           "Bounds", "InputSpec", "OutputSpec", "Structure", "default_bounds", "mimo_structure",
           "siso_structure"]
