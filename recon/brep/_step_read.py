"""Read a STEP file with the face names it carries (XCAF), for the deviation analysis.

Face names live on XCAF sub-shape labels (``TDataStd_Name``); a writer such as
``STEPCAFControl_Writer`` with ``write.stepcaf.subshapes.name`` set stores them there. A face
without a name is called ``face_<i>`` (its index in :func:`faces_of`, from 0).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from OCP.BRep import BRep_Builder
from OCP.IFSelect import IFSelect_RetDone
from OCP.Interface import Interface_Static
from OCP.STEPCAFControl import STEPCAFControl_Controller, STEPCAFControl_Reader
from OCP.TCollection import TCollection_ExtendedString
from OCP.TDataStd import TDataStd_Name
from OCP.TDF import TDF_ChildIterator, TDF_LabelSequence
from OCP.TDocStd import TDocStd_Document
from OCP.TopAbs import TopAbs_FACE
from OCP.TopExp import TopExp
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS, TopoDS_Compound, TopoDS_Shape
from OCP.TopTools import TopTools_IndexedMapOfShape
from OCP.XCAFDoc import XCAFDoc_DocumentTool, XCAFDoc_ShapeTool

from ..errors import InputError

__all__ = ["read_step", "faces_of", "read_back_shape"]

log = logging.getLogger(__name__)


def faces_of(shape: TopoDS_Shape) -> list:
    """The distinct faces of ``shape`` (``TopoDS_Face``), in ``TopExp.MapShapes`` order.

    This order defines the face index used by :func:`read_step` names and the deviation report.
    """
    fmap = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, fmap)
    return [TopoDS.Face_s(fmap.FindKey(i)) for i in range(1, fmap.Extent() + 1)]


def _label_name(label) -> str | None:
    # OCP-NOTES: FindAttribute on a missing attribute crashed the process; ask IsAttribute first.
    if not label.IsAttribute(TDataStd_Name.GetID_s()):
        return None
    attr = TDataStd_Name()
    if not label.FindAttribute(TDataStd_Name.GetID_s(), attr):
        return None
    name = attr.Get().ToExtString()
    return name or None


def read_step(path: str | os.PathLike) -> tuple[TopoDS_Shape, tuple[str, ...]]:
    """Read a STEP file and the names of its faces.

    Parameters
    ----------
    path : str or path-like
        A STEP (AP203/AP214/AP242) file.

    Returns
    -------
    shape : TopoDS_Shape
        The file's free shapes (one shape, or a compound of several).
    face_names : tuple of str, length ``len(faces_of(shape))``
        The XCAF name of each face, or ``"face_<i>"`` where the file names none.

    Raises
    ------
    InputError
        The file is missing, not STEP, or holds no face.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"STEP file {path} does not exist")
    # Sub-shape (face) names are read only when this static is on; it exists once the XCAF STEP
    # controller is initialised. It is process-global: set it for this read and put it back.
    STEPCAFControl_Controller.Init_s()
    old = Interface_Static.IVal_s("read.stepcaf.subshapes.name")
    Interface_Static.SetIVal_s("read.stepcaf.subshapes.name", 1)
    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    reader = STEPCAFControl_Reader()
    reader.SetNameMode(True)
    try:
        status = reader.ReadFile(str(path))
        if status != IFSelect_RetDone:
            raise InputError(f"STEP file {path} could not be read (not a STEP file?)")
        if not reader.Transfer(doc):
            raise InputError(f"STEP file {path}: no shape could be transferred")
    except InputError:
        raise
    except Exception as err:  # OCP raises Standard_Failure subclasses on garbage
        raise InputError(f"STEP file {path} could not be read: {err}".splitlines()[0]) from err
    finally:
        Interface_Static.SetIVal_s("read.stepcaf.subshapes.name", old)

    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    roots = TDF_LabelSequence()
    tool.GetFreeShapes(roots)
    shapes = [XCAFDoc_ShapeTool.GetShape_s(roots.Value(i)) for i in range(1, roots.Length() + 1)]
    shapes = [s for s in shapes if not s.IsNull()]
    if not shapes:
        raise InputError(f"STEP file {path} holds no shape")
    if len(shapes) == 1:
        shape = shapes[0]
    else:
        shape = TopoDS_Compound()
        builder = BRep_Builder()
        builder.MakeCompound(shape)
        for s in shapes:
            builder.Add(shape, s)

    faces = faces_of(shape)
    if not faces:
        raise InputError(f"STEP file {path} holds no face")

    # Named faces, keyed without location so that instances placed by an assembly still match.
    named = TopTools_IndexedMapOfShape()
    names: list[str] = []
    it = TDF_ChildIterator(XCAFDoc_DocumentTool.ShapesLabel_s(doc.Main()), True)
    while it.More():
        label = it.Value()
        it.Next()
        sub = XCAFDoc_ShapeTool.GetShape_s(label)
        if sub.IsNull() or sub.ShapeType() != TopAbs_FACE:
            continue
        name = _label_name(label)
        if name is None:
            continue
        key = sub.Located(TopLoc_Location())
        if named.FindIndex(key) == 0:
            named.Add(key)
            names.append(name)

    face_names = []
    for i, face in enumerate(faces):
        k = named.FindIndex(face.Located(TopLoc_Location()))
        face_names.append(names[k - 1] if k else f"face_{i}")
    log.info("read %s: %d faces, %d named", path, len(faces), sum(1 for n in face_names if n in names))
    return shape, tuple(face_names)


def read_back_shape(path: str | os.PathLike) -> tuple[TopoDS_Shape, tuple[str, ...]]:
    """The shape of a written ``.step``/``.stp``, ``.igs``/``.iges`` or ``.brep`` file and its face names
    (``face_<i>`` where the format holds none: BREP and IGES)."""
    from OCP.BRepTools import BRepTools

    path = Path(path)
    if path.suffix.lower() in (".brep", ".brp"):
        shape = TopoDS_Shape()
        if not BRepTools.Read_s(shape, str(path), BRep_Builder()):
            raise InputError(f"BREP file {path} could not be read back")
    elif path.suffix.lower() in (".igs", ".iges"):
        from ._export import read_iges

        shape = read_iges(path)
    else:
        return read_step(path)
    return shape, tuple(f"face_{i}" for i in range(len(faces_of(shape))))
