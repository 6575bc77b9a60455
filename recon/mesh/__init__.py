"""Mesh stage: read a triangle mesh file and clean it once, keeping the map back to the file's triangles."""

from ._clean import DEFAULT_WELD_RELATIVE, clean_mesh, input_labels
from ._holes import HoleReport, boundary_loops, close_holes
from ._load import SUPPORTED_FORMATS, load_mesh, read_triangles
from ._spikes import SpikeReport, move_spikes
from ._topology import stable_argsort, unique, unique_first
from ._types import CleanReport, Mesh, VertexFaces

__all__ = [
    "CleanReport",
    "DEFAULT_WELD_RELATIVE",
    "HoleReport",
    "Mesh",
    "SUPPORTED_FORMATS",
    "SpikeReport",
    "VertexFaces",
    "boundary_loops",
    "clean_mesh",
    "close_holes",
    "input_labels",
    "load_mesh",
    "move_spikes",
    "read_triangles",
    "stable_argsort",
    "unique",
    "unique_first",
]
