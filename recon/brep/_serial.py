"""OpenCascade shapes and surfaces as bytes, and picklable through them.

A face built in a child process (:func:`recon._parallel.isolated`) comes back through the pipe as pickled bytes,
never through a file: a killed process leaves nothing behind. The bytes are OCC's own BREP text, the format
``BRepTools.Write_s`` writes to a file, so a shape read back is the one a file would have given. Importing this
module registers the picklers (``copyreg``); a spawned child that unpickles a shape imports it first.
"""

from __future__ import annotations

import copyreg
import io

from OCP import Geom
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepTools import BRepTools
from OCP.TopAbs import TopAbs_COMPOUND, TopAbs_EDGE, TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID, TopAbs_VERTEX, TopAbs_WIRE
from OCP.TopoDS import (
    TopoDS,
    TopoDS_Compound,
    TopoDS_Edge,
    TopoDS_Face,
    TopoDS_Shape,
    TopoDS_Shell,
    TopoDS_Solid,
    TopoDS_Vertex,
    TopoDS_Wire,
)

from ..errors import BrepError

__all__ = ["shape_bytes", "shape_from_bytes", "surface_bytes", "surface_from_bytes"]

#: The downcast that gives a shape read back its own Python type.
_DOWNCAST = {
    TopAbs_FACE: TopoDS.Face_s,
    TopAbs_EDGE: TopoDS.Edge_s,
    TopAbs_WIRE: TopoDS.Wire_s,
    TopAbs_VERTEX: TopoDS.Vertex_s,
    TopAbs_SHELL: TopoDS.Shell_s,
    TopAbs_SOLID: TopoDS.Solid_s,
    TopAbs_COMPOUND: TopoDS.Compound_s,
}


def shape_bytes(shape) -> bytes:
    """``shape`` (orientation and location included) as BREP text."""
    out = io.BytesIO()
    BRepTools.Write_s(shape, out)
    return out.getvalue()


def shape_from_bytes(data: bytes):
    """The shape :func:`shape_bytes` wrote, as its own type (``TopoDS_Face`` for a face)."""
    shape = TopoDS_Shape()
    BRepTools.Read_s(shape, io.BytesIO(data), BRep_Builder())
    if shape.IsNull():
        raise BrepError("no shape could be read from the bytes")
    cast = _DOWNCAST.get(shape.ShapeType())
    return cast(shape) if cast else shape


def surface_bytes(surface) -> bytes:
    """A ``Geom_Surface`` as the BREP text of a face on it with no boundary."""
    face = TopoDS_Face()
    BRep_Builder().MakeFace(face, surface, 0.0)
    return shape_bytes(face)


def surface_from_bytes(data: bytes):
    """The ``Geom_Surface`` :func:`surface_bytes` wrote."""
    return BRep_Tool.Surface_s(shape_from_bytes(data))


def _reduce_shape(shape):
    return shape_from_bytes, (shape_bytes(shape),)


def _reduce_surface(surface):
    return surface_from_bytes, (surface_bytes(surface),)


for _kind in (TopoDS_Shape, TopoDS_Face, TopoDS_Edge, TopoDS_Wire, TopoDS_Vertex, TopoDS_Shell, TopoDS_Solid,
              TopoDS_Compound):
    copyreg.pickle(_kind, _reduce_shape)
for _name in ("Geom_Surface", "Geom_Plane", "Geom_CylindricalSurface", "Geom_ConicalSurface", "Geom_SphericalSurface",
              "Geom_ToroidalSurface", "Geom_BSplineSurface", "Geom_BezierSurface", "Geom_SurfaceOfRevolution",
              "Geom_SurfaceOfLinearExtrusion", "Geom_OffsetSurface", "Geom_RectangularTrimmedSurface"):
    copyreg.pickle(getattr(Geom, _name), _reduce_surface)
