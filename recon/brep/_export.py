"""Writing the B-rep: STEP (AP242 or AP214) with a name and colour per face (XCAF), IGES, BREP, STL.

Per-face names and colours survive a STEP round trip only through XCAF sub-shapes (measured, see
shared/OCP-NOTES.md): ``XCAFDoc_ShapeTool.AddSubShape`` + ``TDataStd_Name`` + ``XCAFDoc_ColorTool.SetColor(...,
XCAFDoc_ColorSurf)``, a writer with name and colour modes, and ``write.stepcaf.subshapes.name`` = 1.
"""

from __future__ import annotations

import contextlib
import logging
import os
from pathlib import Path
from typing import Literal

from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.BRepTools import BRepTools
from OCP.IGESControl import IGESControl_Controller, IGESControl_Reader, IGESControl_Writer
from OCP.IFSelect import IFSelect_ReturnStatus
from OCP.Interface import Interface_Static
from OCP.Message import Message, Message_Gravity
from OCP.Quantity import Quantity_Color, Quantity_TypeOfColor
from OCP.StlAPI import StlAPI_Writer
from OCP.STEPCAFControl import STEPCAFControl_Controller, STEPCAFControl_Reader, STEPCAFControl_Writer
from OCP.STEPControl import STEPControl_Controller, STEPControl_StepModelType
from OCP.TCollection import TCollection_ExtendedString
from OCP.TDataStd import TDataStd_Name
from OCP.TopAbs import TopAbs_FACE
from OCP.TDF import TDF_Label, TDF_LabelSequence
from OCP.TDocStd import TDocStd_Document
from OCP.XCAFDoc import XCAFDoc_ColorType, XCAFDoc_DocumentTool

from .._io import atomic_path
from ..errors import ExportError, InputError, UnwritableError
from ._messages import occ_messages
from ._result import KIND_COLOURS, BrepResult, collapsed_face_count, count_shapes

__all__ = ["SCHEMAS", "UNITS", "model_units", "read_iges", "read_step_faces", "write_shape"]

log = logging.getLogger(__name__)

_SUFFIXES = (".step", ".stp", ".igs", ".iges", ".brep", ".brp", ".stl")

Units = Literal["mm", "inch", "m"]
Schema = Literal["AP214", "AP242"]

#: The units a mesh's numbers can be in: OpenCascade's STEP name, its IGES name, and metres per unit. A file
#: declares it and keeps the numbers: a CAD program then shows the part at its true size.
UNITS: dict[str, tuple[str, str, float]] = {"mm": ("MM", "MM", 0.001), "inch": ("INCH", "IN", 0.0254),
                                            "m": ("M", "M", 1.0)}

#: STEP application protocols: AP242 (recon's default: what current CAD reads, with PMI and face names) or AP214
#: (what older readers take), as OpenCascade's ``write.step.schema`` names them.
SCHEMAS: dict[str, str] = {"AP214": "AP214IS", "AP242": "AP242DIS"}


@contextlib.contextmanager
def _static(settings: dict):
    """Set OCC ``Interface_Static`` values for one write, and put the old ones back (they are process-global)."""
    # The controllers define (and on first use reset) the statics: initialise them before setting any.
    STEPControl_Controller.Init_s()
    STEPCAFControl_Controller.Init_s()
    old = {}
    for key, val in settings.items():
        if isinstance(val, int):
            old[key] = Interface_Static.IVal_s(key)
            Interface_Static.SetIVal_s(key, val)
        else:
            old[key] = Interface_Static.CVal_s(key)
            Interface_Static.SetCVal_s(key, val)
    try:
        yield
    finally:
        for key, val in old.items():
            if isinstance(val, int):
                Interface_Static.SetIVal_s(key, val)
            else:
                Interface_Static.SetCVal_s(key, val)


@contextlib.contextmanager
def _quiet():
    """OCC's default messenger sends transfer statistics (to stdout, or within :func:`occ_messages` to the debug
    log): none below failures, they are not the user's business."""
    printers = list(Message.DefaultMessenger_s().Printers())
    old = [pr.GetTraceLevel() for pr in printers]
    for pr in printers:
        pr.SetTraceLevel(Message_Gravity.Message_Fail)
    try:
        yield
    finally:
        for pr, lvl in zip(printers, old):
            pr.SetTraceLevel(lvl)


@contextlib.contextmanager
def model_units(units: Units = "mm"):
    """Within it, OpenCascade's STEP and IGES readers give lengths in ``units`` (``xstep.cascade.unit``, which is
    process-global): a file written with ``write_shape(..., units=units)`` reads back with the numbers it was given."""
    _check_units(units, "model_units")
    IGESControl_Controller.Init_s()
    with _static({"xstep.cascade.unit": UNITS[units][0]}):
        yield


def _check_units(units: str, where: str) -> None:
    if units not in UNITS:
        raise InputError(f"{where}: `units` must be one of {', '.join(UNITS)}, got {units!r}")


def _occ(shape):
    return getattr(shape, "wrapped", shape)


def _write_step(tmp: Path, result: BrepResult, name: str, units: str, schema: str) -> None:
    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    # the document's length unit: the shape's numbers are in `units`, and the file says so (no scaling)
    XCAFDoc_DocumentTool.SetLengthUnit_s(doc, UNITS[units][2])
    shape_tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colour_tool = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
    root = shape_tool.AddShape(result.occ, False)
    TDataStd_Name.Set_s(root, TCollection_ExtendedString(name))
    for rec in result.faces:
        if rec.face is None:
            continue
        sub = shape_tool.AddSubShape(root, rec.face)
        if sub.IsNull():
            log.warning("write_shape: face %s is not a sub-shape of the result; not named", rec.name)
            continue
        TDataStd_Name.Set_s(sub, TCollection_ExtendedString(rec.name))
        r, g, b = KIND_COLOURS.get(rec.kind, KIND_COLOURS["patch"])
        colour_tool.SetColor(sub, Quantity_Color(r, g, b, Quantity_TypeOfColor.Quantity_TOC_sRGB),
                             XCAFDoc_ColorType.XCAFDoc_ColorSurf)
    settings = {"write.stepcaf.subshapes.name": 1, "write.step.schema": SCHEMAS[schema],
                "write.step.unit": UNITS[units][0]}
    with _static(settings), occ_messages(), _quiet():
        writer = STEPCAFControl_Writer()
        writer.SetNameMode(True)
        writer.SetColorMode(True)
        if not writer.Transfer(doc, STEPControl_StepModelType.STEPControl_AsIs):
            raise ExportError(f"cannot write {tmp.name}: STEPCAFControl_Writer.Transfer failed")
        if not _step_faces(writer.ChangeWriter().Model()):
            # the transfer skips a face with no edge of length (and the solid of nothing else) and still succeeds
            raise UnwritableError(f"OpenCascade's STEP writer took none of the {count_shapes(result.occ, TopAbs_FACE)} "
                                  f"faces ({collapsed_face_count(result.occ)} have no area): nothing written")
        status = writer.Write(str(tmp))
    if status != IFSelect_ReturnStatus.IFSelect_RetDone:
        raise ExportError(f"cannot write STEP: writer returned {status}")


def _step_faces(model) -> int:
    """The faces (``ADVANCED_FACE``, ``FACE_SURFACE``) in a STEP model made by a writer's transfer."""
    from OCP.StepShape import StepShape_FaceSurface

    kind = StepShape_FaceSurface.get_type_descriptor_s()  # (ADVANCED_FACE is a kind of FACE_SURFACE)
    return sum(model.Value(i).IsKind(kind) for i in range(1, model.NbEntities() + 1))


def _write_iges(tmp: Path, occ, units: str) -> None:
    IGESControl_Controller.Init_s()
    writer = IGESControl_Writer(UNITS[units][1], 1)  # 1: BRep mode (faces, shells, solids), not trimmed surfaces
    # the model's own length unit, in mm (OpenCascade's default): the shape's numbers are in `units`, not scaled
    section = writer.Model().GlobalSection()
    section.SetCascadeUnit(1000.0 * UNITS[units][2])
    writer.Model().SetGlobalSection(section)
    if not writer.AddShape(occ):
        raise ExportError(f"cannot write {tmp.name}: IGESControl_Writer.AddShape failed")
    writer.ComputeModel()
    if not writer.Write(str(tmp)):
        raise ExportError(f"cannot write {tmp.name}: IGESControl_Writer.Write failed")


def write_shape(path: str | os.PathLike, result: BrepResult, *, name: str = "recon", deflection: float = 0.01,
                units: Units = "mm", schema: Schema = "AP242") -> Path:
    """Write a B-rep result; the format follows the extension (.step/.stp, .igs/.iges, .brep, .stl).

    Parameters
    ----------
    path : path-like
        Output file; written atomically (a temporary name, renamed on success).
    result : BrepResult
        From :func:`recon.brep.build_solid`.
    name : str
        Product name in the STEP file.
    deflection : float
        Linear deflection of the STL tessellation (model units).
    units : "mm", "inch" or "m"
        The unit of the shape's numbers (the mesh's), which a STEP or IGES file declares: a CAD program shows the part
        at its true size. BREP and STL files carry no unit.
    schema : "AP242" or "AP214"
        The STEP application protocol (:data:`SCHEMAS`).

    Returns
    -------
    Path
        The written path.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise InputError(f"write_shape: `path` must end in one of {', '.join(_SUFFIXES)}, got {path.name!r}")
    if not isinstance(result, BrepResult):
        raise InputError(f"write_shape: `result` must be a BrepResult, got {type(result).__name__}")
    _check_units(units, "write_shape")
    if schema not in SCHEMAS:
        raise InputError(f"write_shape: `schema` must be one of {', '.join(SCHEMAS)}, got {schema!r}")
    occ = result.occ
    with atomic_path(path) as tmp, occ_messages():
        if suffix in (".step", ".stp"):
            _write_step(tmp, result, name, units, schema)
        elif suffix in (".igs", ".iges"):
            _write_iges(tmp, occ, units)
        elif suffix in (".brep", ".brp"):
            if not BRepTools.Write_s(occ, str(tmp)):
                raise ExportError(f"cannot write {path}: BRepTools.Write failed")
        else:
            # angular deflection 0.3 rad: OCC's usual tessellation angle (scale-free)
            mesher = BRepMesh_IncrementalMesh(occ, float(deflection), False, 0.3, True)
            if not mesher.IsDone():
                raise ExportError(f"cannot write {path}: tessellation failed")
            if not StlAPI_Writer().Write(occ, str(tmp)):
                raise ExportError(f"cannot write {path}: StlAPI_Writer failed")
    log.info("wrote %s", path)
    return path


def read_iges(path: str | os.PathLike):
    """The shape of an IGES file (its roots; one shape or a compound), in :func:`model_units`' unit (default mm)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"IGES file {path} does not exist")
    IGESControl_Controller.Init_s()
    reader = IGESControl_Reader()
    with occ_messages(), _quiet():
        if reader.ReadFile(str(path)) != IFSelect_ReturnStatus.IFSelect_RetDone:
            raise InputError(f"{path} could not be read as IGES")
        reader.TransferRoots()
    shape = reader.OneShape()
    if shape.IsNull():
        raise InputError(f"IGES file {path} holds no shape")
    return shape


def _label_name(label: TDF_Label) -> str | None:
    attr = TDataStd_Name()
    # FindAttribute on a missing attribute has crashed the process (OCP-NOTES): ask first.
    if not label.IsAttribute(TDataStd_Name.GetID_s()):
        return None
    if label.FindAttribute(TDataStd_Name.GetID_s(), attr):
        return attr.Get().ToExtString()
    return None


def read_step_faces(path: str | os.PathLike) -> list[tuple[str | None, tuple[float, float, float] | None]]:
    """Names and surface colours of the face sub-shapes of a STEP file, read back through XCAF.

    Returns
    -------
    list of (name, (r, g, b) or None)
        One entry per face sub-shape label of every free shape, in file order.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"read_step_faces: `path` {path} is not a file")
    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    reader = STEPCAFControl_Reader()
    reader.SetNameMode(True)
    reader.SetColorMode(True)
    with _static({"read.stepcaf.subshapes.name": 1}), occ_messages(), _quiet():
        if reader.ReadFile(str(path)) != IFSelect_ReturnStatus.IFSelect_RetDone:
            raise InputError(f"read_step_faces: cannot read {path} as STEP")
        if not reader.Transfer(doc):
            raise InputError(f"read_step_faces: cannot transfer {path}")
    shape_tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colour_tool = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
    free = TDF_LabelSequence()
    shape_tool.GetFreeShapes(free)
    out = []
    for i in range(1, free.Length() + 1):
        subs = TDF_LabelSequence()
        shape_tool.GetSubShapes_s(free.Value(i), subs)
        for j in range(1, subs.Length() + 1):
            lab = subs.Value(j)
            colour = Quantity_Color()
            rgb = None
            if colour_tool.GetColor_s(lab, XCAFDoc_ColorType.XCAFDoc_ColorSurf, colour):
                rgb = colour.Values(Quantity_TypeOfColor.Quantity_TOC_sRGB)
            out.append((_label_name(lab), rgb))
    return out
