"""Output: the parallel HDF5 file and its layout (:mod:`.hdf5`,
:mod:`.layout`, :mod:`.plan`), the XDMF files for ParaView (:mod:`.xdmf`),
the per-step CSV history (:mod:`.history`), the fields a simulation writes
(:mod:`.fields`) and the output directory (:mod:`.directory`)."""
from .directory import OUTPUT_FILES, prepare_output_directory
from .fields import grid_fields, particle_fields, write_results
from .hdf5 import ResultWriter
from .history import History
from .layout import GRID_XDMF, H5_NAME, PARTICLES_XDMF

__all__ = ["GRID_XDMF", "H5_NAME", "OUTPUT_FILES", "PARTICLES_XDMF", "History", "ResultWriter",
           "grid_fields", "particle_fields", "prepare_output_directory", "write_results"]
