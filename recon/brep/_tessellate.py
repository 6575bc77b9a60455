"""A CAD shape as a labelled triangle mesh with its true surfaces: ground truth for the B-rep stage."""

from __future__ import annotations

import logging

import numpy as np
from OCP.BRep import BRep_Tool
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
from OCP.TopExp import TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS
from scipy.spatial import cKDTree

from ..errors import BrepError, InputError

__all__ = ["labelled_tessellation", "result_tessellation", "display_deflection", "unmeshed_faces"]

log = logging.getLogger(__name__)

#: FreeCAD's display tessellation (Part view provider, its defaults): linear deflection ``Deviation`` = 0.5 % of the
#: mean side of the shape's bounding box ((dx + dy + dz) / 300 × 0.5: scales with the part's size), absolute, in
#: parallel. A face that gets no triangles there shows as a hole in FreeCAD (issue 25).
DISPLAY_DEVIATION = 0.005
#: FreeCAD's default ``AngularDeflection`` (a fixed angle: the turn between facets, scale-free)
DISPLAY_ANGLE = float(np.deg2rad(28.5))


def _wrapped(shape):
    return getattr(shape, "wrapped", shape)


def labelled_tessellation(shape, *, deflection: float, angular: float = 0.3, weld: float = 1e-7,
                          skip_unmeshed: bool = False):
    """Tessellate every face of ``shape`` and label each triangle by its face.

    Parameters
    ----------
    shape : build123d Shape or TopoDS_Shape
    deflection : float
        Linear deflection of the tessellation (model units).
    angular : float
        Angular deflection in radians.
    weld : float
        Vertices closer than this are merged (OpenCascade meshes shared edges identically on both faces).
    skip_unmeshed : bool
        Leave out (with a warning) a face OpenCascade's mesher gives no triangles, instead of raising
        :class:`~recon.errors.BrepError`: for pictures, where one such face must not cost the rest. Ground
        truth needs every face, so the default raises.

    Returns
    -------
    vertices : (n, 3) float
    faces : (m, 3) int
        Oriented outward (the face orientation is applied).
    labels : (m,) int
        Index of the face (in ``TopExp_Explorer`` order) each triangle came from.
    surfaces : list of Geom_Surface
        The true surface of each face (location applied), indexed by label.
    """
    if not deflection > 0:
        raise InputError(f"labelled_tessellation: `deflection` must be > 0, got {deflection!r}")
    occ = _wrapped(shape)
    mesher = BRepMesh_IncrementalMesh(occ, float(deflection), False, float(angular), True)
    if not mesher.IsDone():
        raise BrepError("labelled_tessellation: BRepMesh_IncrementalMesh failed")
    verts, tris, labels, surfaces = [], [], [], []
    base = 0
    exp = TopExp_Explorer(occ, TopAbs_FACE)
    label = 0
    while exp.More():
        face = TopoDS.Face_s(exp.Current())
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is None:
            if not skip_unmeshed:
                raise BrepError(f"labelled_tessellation: face {label} has no triangulation")
            log.warning("face %d could not be meshed: it is left out of the picture", label)
            surfaces.append(BRep_Tool.Surface_s(face))
            label += 1
            exp.Next()
            continue
        trsf = loc.Transformation()
        nodes = np.array([[(p := tri.Node(i).Transformed(trsf)).X(), p.Y(), p.Z()]
                          for i in range(1, tri.NbNodes() + 1)])
        t = np.array([tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)], dtype=np.int64) - 1
        if face.Orientation() == TopAbs_REVERSED:
            t = t[:, [0, 2, 1]]
        verts.append(nodes)
        tris.append(t + base)
        labels.append(np.full(len(t), label, dtype=np.int64))
        surf = BRep_Tool.Surface_s(face)  # with the face's location applied
        surfaces.append(surf)
        base += len(nodes)
        label += 1
        exp.Next()
    if not verts:
        raise InputError("labelled_tessellation: `shape` has no faces" + (" it could mesh" if label else ""))
    v = np.concatenate(verts)
    f = np.concatenate(tris)
    lab = np.concatenate(labels)
    # Weld: union of near-coincident vertices, representative = smallest index.
    pairs = cKDTree(v).query_pairs(weld, output_type="ndarray")
    rep = np.arange(len(v))
    for a, b in sorted(map(tuple, pairs.tolist())):
        ra, rb = rep[a], rep[b]
        while rep[ra] != ra:
            ra = rep[ra]
        while rep[rb] != rb:
            rb = rep[rb]
        if ra != rb:
            rep[max(ra, rb)] = min(ra, rb)
    for i in range(len(rep)):
        r = i
        while rep[r] != r:
            r = rep[r]
        rep[i] = r
    keep, inverse = np.unique(rep, return_inverse=True)
    f = inverse[f]
    good = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    return v[keep], f[good], lab[good], surfaces


def result_tessellation(result, *, deflection: float):
    """Tessellate a :class:`~recon.brep.BrepResult` for pictures: vertices, faces, face label per triangle, and
    the part kind (``"patch"``, ``"linear"``, ``"junction"``, ``"terminal"``) of every label. A face the mesher
    cannot triangulate is left out with a warning (the shape was already written: the picture shows the rest)."""
    v, f, lab, _ = labelled_tessellation(result.occ, deflection=deflection, skip_unmeshed=True)
    kinds = []
    exp = TopExp_Explorer(result.occ, TopAbs_FACE)
    while exp.More():
        face = exp.Current()
        kinds.append(next((r.kind for r in result.faces if r.face is not None and r.face.IsSame(face)), "patch"))
        exp.Next()
    return v, f, lab, kinds


def display_deflection(shape) -> float:
    """FreeCAD's display deflection for ``shape``: :data:`DISPLAY_DEVIATION` × the mean side of its bounding box
    (OpenCascade's box of the shape, no gap), and OpenCascade's confusion for a shape of no size."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib
    from OCP.Precision import Precision

    box = Bnd_Box()
    BRepBndLib.Add_s(_wrapped(shape), box)
    box.SetGap(0.0)
    if box.IsVoid():
        return float(Precision.Confusion_s())
    x0, y0, z0, x1, y1, z1 = box.Get()
    return box_display_deflection(np.array([x0, y0, z0]), np.array([x1, y1, z1]))


def box_display_deflection(lo: np.ndarray, hi: np.ndarray) -> float:
    """FreeCAD's display deflection for a bounding box ``lo``..``hi`` (:func:`display_deflection`)."""
    from OCP.Precision import Precision

    return max(DISPLAY_DEVIATION * float(np.mean(np.asarray(hi) - np.asarray(lo))), float(Precision.Confusion_s()))


def has_triangles(face) -> bool:
    """Whether ``face`` holds a triangulation with at least one triangle."""
    tri = BRep_Tool.Triangulation_s(face, TopLoc_Location())
    return tri is not None and tri.NbTriangles() > 0


def unmeshed_faces(shape) -> list[int]:
    """The faces (indices in :func:`recon.brep._step_read.faces_of` order) that OpenCascade's mesher leaves without
    a triangle at FreeCAD's display settings (:data:`DISPLAY_DEVIATION`, :data:`DISPLAY_ANGLE`).

    Meshed on a copy without triangulation, as FreeCAD meshes a shape it has just read: BRepMesh refines a
    triangulation it finds instead of starting afresh (and the caller's shape keeps none of it).
    """
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy

    from ._step_read import faces_of

    copy = BRepBuilderAPI_Copy(_wrapped(shape), True, False).Shape()
    try:
        BRepMesh_IncrementalMesh(copy, display_deflection(copy), False, DISPLAY_ANGLE, True)
    except Exception as err:  # noqa: BLE001  (OCC raises Standard_Failure: then no face got its triangles)
        log.warning("BRepMesh failed on the whole shape (%s: %s)", type(err).__name__, err)
    return [i for i, face in enumerate(faces_of(copy)) if not has_triangles(face)]
