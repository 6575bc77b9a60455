"""recon's B-rep in CadQuery (the ``cadquery`` extra: ``pip install "recon[cadquery]"``).

CadQuery runs on the same OpenCascade build as build123d (OCP 7.9.3), so a result passes by reference, no file in
between:

>>> import recon                                                     # doctest: +SKIP
>>> solid = recon.to_cadquery(recon.convert("part.stl"))             # doctest: +SKIP
>>> drilled = cadquery.Workplane(obj=solid).faces(">Z").workplane().hole(5.0)  # doctest: +SKIP
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import cadquery

    from ..pipeline import Conversion

__all__ = ["to_cadquery"]


def to_cadquery(shape: Conversion | Any) -> cadquery.Shape:
    """The B-rep of a result as a CadQuery shape (``cadquery.Solid`` for a solid, ``Shell`` or ``Compound`` else).

    Parameters
    ----------
    shape : Conversion, recon.brep.BrepResult, build123d Shape or OCP TopoDS_Shape
        What :func:`recon.convert` or :func:`recon.build_solid` returned, or the shape itself.

    Returns
    -------
    cadquery.Shape
        The same OpenCascade shape (not a copy), typed by CadQuery: keep modelling with ``cadquery.Workplane(obj=…)``.

    Raises
    ------
    ImportError
        CadQuery is not installed (``pip install "recon[cadquery]"``).
    TypeError
        ``shape`` is none of the above.
    """
    try:
        import cadquery as cq
    except ImportError as err:
        raise ImportError('recon.to_cadquery needs CadQuery: pip install "recon[cadquery]"') from err
    from OCP.TopoDS import TopoDS_Shape

    occ = shape
    for attr in ("brep", "occ"):  # Conversion -> BrepResult -> TopoDS_Shape
        occ = getattr(occ, attr, occ)
    occ = getattr(occ, "wrapped", occ)  # a build123d (or CadQuery) shape
    if not isinstance(occ, TopoDS_Shape):
        raise TypeError(f"to_cadquery takes a recon result or a shape, not {type(shape).__name__}")
    return cq.Shape.cast(occ)
