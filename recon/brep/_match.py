"""Each face record attached to its face in the final shape, which healing and sewing may have rebuilt."""

from __future__ import annotations

import numpy as np
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex

from ._edges import pnt
from ._result import FaceRecord


def match_faces(records, final_faces, network):
    """Attach each record to its face in the final shape: same TShape first, else nearest sample point (the first
    face in ``final_faces`` at the least distance)."""
    out = []
    taken = set()
    boxes = None
    for rec in records:
        match = None
        if rec.face is not None:
            for i, f in enumerate(final_faces):
                if i not in taken and f.IsSame(rec.face):
                    match = i
                    break
        if match is None and rec.face is not None:
            from OCP.BRepExtrema import BRepExtrema_DistShapeShape

            pts, _ = network.part_samples(rec.part)
            if len(pts):
                p = pts[len(pts) // 2]
                vtx = BRepBuilderAPI_MakeVertex(pnt(p)).Vertex()
                # A face's box bounds its distance from below: the faces are measured nearest box first, and none
                # whose box is farther than the least distance found can be nearer (a sewn shell rebuilds every
                # face, and measuring each against all is quadratic in the face count).
                if boxes is None:
                    boxes = _face_boxes(final_faces)
                free = [i for i in range(len(final_faces)) if i not in taken]
                lower = dict(zip(free, _box_distances(boxes[free], p)))
                best = None
                for i in sorted(free, key=lambda i: (lower[i], i)):
                    if best is not None and lower[i] > best[0]:
                        break
                    d = BRepExtrema_DistShapeShape(vtx, final_faces[i])
                    if d.IsDone() and (best is None or (d.Value(), i) < best):
                        best = (d.Value(), i)
                match = best[1] if best else None
        if match is not None:
            taken.add(match)
        face = final_faces[match] if match is not None else None
        out.append(FaceRecord(rec.part, rec.name, rec.kind, rec.surface_type, rec.status, rec.area, face, rec.message))
    return out


def _face_boxes(faces) -> np.ndarray:
    """(k, 6) float: (xmin, ymin, zmin, xmax, ymax, zmax) of each face's bounding box from its geometry (not its
    triangulation, which can lie inside the surface), widened by a thousandth of the whole's diagonal so that
    round-off cannot put a face outside its box."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    out = np.empty((len(faces), 6))
    for i, f in enumerate(faces):
        box = Bnd_Box()
        BRepBndLib.Add_s(f, box, False)
        out[i] = (-np.inf,) * 3 + (np.inf,) * 3 if box.IsVoid() or box.IsOpen() else box.Get()
    finite = np.all(np.isfinite(out), axis=1)
    if finite.any():
        # box margin: a thousandth of the boxes' diagonal (scales with part size)
        margin = 1e-3 * float(np.linalg.norm(out[finite, 3:].max(axis=0) - out[finite, :3].min(axis=0)))
        out[:, :3] -= margin
        out[:, 3:] += margin
    return out


def _box_distances(boxes: np.ndarray, p) -> np.ndarray:
    """Distance of the point ``p`` (3,) to each box of ``boxes`` (k, 6) (0 inside)."""
    gap = np.maximum(np.maximum(boxes[:, :3] - p, p - boxes[:, 3:]), 0.0)
    return np.linalg.norm(gap, axis=1)
