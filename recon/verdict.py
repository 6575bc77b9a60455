"""Acceptance rules: recon checks its own result before it calls it good.

A conversion is good (``recon convert`` exits 0) only when every rule holds; the report's ``verdict`` section lists
each rule with its figure, its limit and the faces where it fails. T is the tolerance the run used.

* ``solid``: the written file, read back from disk, is one valid closed solid (type SOLID, BRepCheck valid, closed
  shell, no free edge, volume > 0; a mesh of several disjoint bodies gives a compound of such solids). For a mesh still
  open after its small holes were closed over (:func:`recon.mesh.close_holes`) a valid shell is the right answer. An ``.stl`` output is read back as a mesh: watertight,
  consistently wound, positive volume.
* ``coverage``: every part of the mesh has a face.
* ``overlap``: no closed shell of the mesh crosses another or lies inside another. Every closed shell becomes a solid
  of its own, so overlapping shells would give overlapping solids and a wrong volume.
* ``mesh_to_shape_p95`` ≤ T and ``mesh_to_shape_max`` ≤ k·T (:data:`MAX_PER_TOLERANCE`): the mesh's vertices lie on
  the faces.
* ``shape_to_mesh_p95`` ≤ T + the mesh's sag (the area's 95th percentile of :func:`triangle_sag`) and, face by face,
  ``shape_to_mesh_max`` ≤ k·T + the largest sag of the face's triangles and their neighbours: the faces lie on the
  mesh, except where the mesh is a coarse tessellation of a curved face whose flat triangles cut inside it by their
  chord sag.
* ``volume``: |V_shape − V_mesh| ≤ Σ area_t · (T + sag_t) over the triangles, for a closed mesh: the volume between
  two surfaces within T + sag of each other. It holds whenever the two-way bound holds, and it still checks a run
  that skipped the deviation (``deviation=False``).
* ``meshable``: every face gets triangles from OpenCascade's mesher at FreeCAD's display settings
  (:func:`recon.brep._tessellate.unmeshed_faces`): a face without them shows as a hole in FreeCAD and in any viewer
  that meshes the same way.
* ``face_count``: where the faces were found from a CAD export's exact vertices, the vertices prove their count: no
  face on which they hold another count as well (a torus on three rings of vertices is one face or two bands of
  cones; ``exact_vertices.open_count`` in the report says which).

Without a measured deviation the four deviation rules are "not checked" (``ok`` None): the verdict is then ``ok``
when every other rule holds, and ``within_tolerance`` is None, never True.
"""

from __future__ import annotations

import json
import logging
import os
import time
import weakref
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ._tolerance import SMOOTH_TURN  # (one value for the verdict's sag and the B-rep's reach margin)

__all__ = ["Rule", "Verdict", "judge", "triangle_sag", "overlapping_shells", "read_back", "write_checked",
           "strict_json", "unmeshed_names", "MAX_PER_TOLERANCE", "SMOOTH_TURN", "RULES"]

log = logging.getLogger(__name__)

#: The rules in the order the report lists them.
RULES = ("solid", "coverage", "meshable", "overlap", "mesh_to_shape_p95", "mesh_to_shape_max", "shape_to_mesh_p95",
         "shape_to_mesh_max", "volume", "face_count")
_DEVIATION_RULES = ("mesh_to_shape_p95", "mesh_to_shape_max", "shape_to_mesh_p95", "shape_to_mesh_max")

#: k: the largest deviation allowed is k·T. The fit stage accepts a surface with its max within 2T; with the default
#: T = 4σ that is 8σ, and the max of |N(0, σ)| over 10⁷ points passes 5.5σ with probability 1 − exp(−10⁷ · 3.8e-8)
#: ≈ 32 % and 6σ with 2 %: 2T leaves the fit about 2σ of its own.
MAX_PER_TOLERANCE = 2.0


#: Points of one closed shell tested against another for :func:`overlapping_shells` (vertices first, then centroids):
#: an overlap covering less than about 1/this of a shell's samples can go unseen.
OVERLAP_SAMPLES = 4000


#: The sag of each mesh judged (it depends on the mesh alone; a conversion is judged in memory, then on its file).
_SAGS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _sag_of(mesh) -> np.ndarray:
    if mesh not in _SAGS:
        _SAGS[mesh] = triangle_sag(mesh)
    return _SAGS[mesh]


def _file_rules(validity: dict, mesh, sag: np.ndarray, tolerance: float, source: str,
                unmeshed: list | None) -> tuple[Rule, Rule, Rule]:
    """The rules that judge what was built or written: ``solid``, ``volume`` and ``meshable``."""
    closed = mesh.report.boundary_edges == 0
    return (_solid_rule(validity, not closed, source),
            _volume_rule(validity, mesh, sag, tolerance, closed and mesh.report.non_manifold_edges == 0),
            _meshable_rule(unmeshed, source))


# --------------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Rule:
    """One acceptance rule's outcome.

    ``ok`` is None when the rule was not checked (a run without deviation; an open mesh has no volume); ``value``
    and ``limit`` are numbers in model units (or, for ``solid``, what the file holds and what it must hold);
    ``faces`` names the faces where the rule fails; ``detail`` says it in a sentence.
    """

    rule: str
    ok: bool | None
    value: Any = None
    limit: Any = None
    faces: tuple[str, ...] = ()
    detail: str = ""

    def to_json(self) -> dict:
        return {"rule": self.rule, "ok": self.ok, "value": strict_json(self.value), "limit": strict_json(self.limit),
                "faces": list(self.faces), "detail": self.detail}

    @classmethod
    def from_json(cls, d: dict) -> Rule:
        return cls(d["rule"], d["ok"], d.get("value"), d.get("limit"), tuple(d.get("faces", ())), d.get("detail", ""))


@dataclass(frozen=True)
class Verdict:
    """All rules; ``ok`` when none failed. ``within_tolerance`` is None when the deviation was not measured."""

    rules: tuple[Rule, ...]
    seconds: float = field(default=0.0, compare=False)

    @property
    def ok(self) -> bool:
        return all(r.ok is not False for r in self.rules)

    @property
    def within_tolerance(self) -> bool | None:
        dev = [r.ok for r in self.rules if r.rule in _DEVIATION_RULES]
        if any(ok is False for ok in dev):
            return False
        return None if any(ok is None for ok in dev) else True

    @property
    def failed(self) -> list[Rule]:
        return [r for r in self.rules if r.ok is False]

    def rule(self, name: str) -> Rule:
        return next(r for r in self.rules if r.rule == name)

    def with_rules(self, *rules: Rule) -> Verdict:
        """The verdict with the rules of the same names replaced."""
        new = {r.rule: r for r in rules}
        return replace(self, rules=tuple(new.get(r.rule, r) for r in self.rules))

    def to_json(self) -> dict:
        return {"ok": self.ok, "within_tolerance": self.within_tolerance, "seconds": round(self.seconds, 4),
                "rules": [r.to_json() for r in self.rules]}

    @classmethod
    def from_json(cls, d: dict) -> Verdict:
        return cls(tuple(Rule.from_json(r) for r in d["rules"]), d.get("seconds", 0.0))


def strict_json(x):
    """``x`` with every non-finite float replaced by None (strict JSON has no NaN or Infinity), numpy scalars made
    Python ones."""
    if isinstance(x, dict):
        return {k: strict_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [strict_json(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


# --------------------------------------------------------------------------------------------------
# What the mesh tells
# --------------------------------------------------------------------------------------------------


def triangle_sag(mesh, *, block: int = 100_000) -> np.ndarray:
    """How far a curved face the mesh tessellates may bulge beyond each triangle: its chord sag, from the mesh alone.

    The triangle's corners lie on the surface. Each corner gets the normal of the triangles around it that turn by
    less than :data:`SMOOTH_TURN` from this one (a crease splits the normals, as a renderer's smoothing angle does);
    along an edge i→j the surface then curves by κ_ij = (N_j − N_i)·(P_j − P_i) / ℓ², and a quadratic surface through
    the corners lies off the flat triangle by e(λ) = ½ Σ λ_i λ_j κ_ij ℓ_ij² at barycentric λ (the linear
    interpolation error), each κ_ij ℓ_ij² divided by cos²(φ_ij / 4) for the turn φ_ij between the corners' normals:
    the circle's sag over the parabola's, so that an arc's midpoint sag is the circle's. The sag is its largest
    magnitude over the triangle: r (1 − cos(π / n)) for a regular n-gon prism's facets, about a² / (6 r) for an
    equilateral triangle of side a on a sphere of radius r; zero on planes. A
    triangle on a crease also gets the crease's own offset (:func:`_crease_sag`).

    Parameters
    ----------
    mesh : recon.mesh.Mesh
    block : int
        Triangles handled at once (bounds the memory: about 1 KB per triangle).

    Returns
    -------
    (m,) float
    """
    V, F = mesh.vertices, mesh.faces
    m = len(F)
    n = mesh.face_normals
    angles = _corner_angles(V, F)
    vf = mesh.vertex_faces
    per_vertex = np.diff(vf.offsets)
    cos_smooth = np.cos(SMOOTH_TURN)
    # barycentric points at steps of 1/6: the edge midpoints and the centroid, where the extremes of e lie
    g = np.array([(a, b, 6 - a - b) for a in range(7) for b in range(7 - a)], dtype=float) / 6.0
    out = np.empty(m)
    for lo in range(0, m, block):
        t_ids = np.arange(lo, min(lo + block, m))
        corner_v = F[t_ids].ravel()
        counts = per_vertex[corner_v]
        rows = np.repeat(np.arange(len(corner_v)), counts)
        first = np.repeat(vf.offsets[corner_v] - (np.cumsum(counts) - counts), counts)
        s = vf.indices[np.arange(len(rows)) + first]
        t = t_ids[rows // 3]
        keep = np.einsum("ij,ij->i", n[t], n[s]) > cos_smooth
        rows, s, v = rows[keep], s[keep], corner_v[rows[keep]]
        # weighted by the angle at the corner: the tessellation-independent vertex normal (a fan's triangle count
        # around a vertex does not tilt it)
        w = angles[s, np.argmax(F[s] == v[:, None], axis=1)]
        N = np.stack([np.bincount(rows, weights=w * n[s, c], minlength=len(corner_v)) for c in range(3)], axis=1)
        N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)
        N = N.reshape(-1, 3, 3)
        P = V[F[t_ids]]
        ends = ((0, 1), (1, 2), (2, 0))
        q = np.stack([np.einsum("ij,ij->i", N[:, j] - N[:, i], P[:, j] - P[:, i]) for i, j in ends], axis=1)  # κ_ij ℓ_ij²
        # the parabola's midpoint sag of an arc turning by φ is the circle's times cos²(φ/4): scaled back to the circle
        phi = np.arccos(np.clip(np.stack([np.einsum("ij,ij->i", N[:, i], N[:, j]) for i, j in ends], axis=1), -1, 1))
        q /= np.cos(phi / 4) ** 2
        pairs = np.stack([g[:, 0] * g[:, 1], g[:, 1] * g[:, 2], g[:, 2] * g[:, 0]], axis=1)  # (k, 3)
        out[t_ids] = 0.5 * np.abs(q @ pairs.T).max(axis=1)
    return np.maximum(out, _crease_sag(mesh, out))


#: The sharpest crease :func:`_crease_sag` measures: past it the two faces fold onto each other (a knife edge), and the
#: true edge's offset along their bisector grows without bound; it is taken as at this turn.
_FOLD_TURN = np.deg2rad(135.0)


def _crease_sag(mesh, sag: np.ndarray) -> np.ndarray:
    """(m,) float: how far the true edge at a crease may lie from the mesh's crease edge.

    The crease's vertices lie on the true edge, which bulges off the chord between them: off triangle A's plane by its
    sag s_A and off B's by s_B, so by |d|² = (s_A² + s_B² − 2 s_A s_B cos φ) / sin² φ with φ the turn between the two
    normals (s_A / sin φ where B is flat: a plane capping a coarse cylinder overhangs its polygon by the cylinder's
    sag; √2 s where two coarse fillets meet at 90°). Zero where both sides are flat: a box's corners have none.
    """
    out = np.zeros(len(sag))
    pairs = mesh.face_adjacency
    if not len(pairs):
        return out
    a, b = pairs[:, 0], pairs[:, 1]
    n = mesh.face_normals
    phi = np.arccos(np.clip(np.einsum("ij,ij->i", n[a], n[b]), -1.0, 1.0))
    crease = phi >= SMOOTH_TURN
    a, b, phi = a[crease], b[crease], np.minimum(phi[crease], _FOLD_TURN)
    sa, sb = sag[a], sag[b]
    d = np.sqrt(np.maximum(sa * sa + sb * sb - 2.0 * sa * sb * np.cos(phi), 0.0)) / np.sin(phi)
    np.maximum.at(out, a, d)
    np.maximum.at(out, b, d)
    return out


def _corner_angles(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m, 3) float: each triangle's angle at each of its corners."""
    P = V[F]
    out = np.empty(F.shape)
    for k in range(3):
        a, b = P[:, (k + 1) % 3] - P[:, k], P[:, (k + 2) % 3] - P[:, k]
        out[:, k] = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))
    return out


def _closed_components(mesh) -> list[np.ndarray]:
    """Triangle indices of every edge-connected component whose edges all carry exactly two of its triangles."""
    comp = np.asarray(mesh.component)
    count = mesh.edge_face_count[mesh.face_edges]  # (m, 3)
    open_comp = np.zeros(int(comp.max()) + 1, dtype=bool)
    open_comp[comp[(count != 2).any(axis=1)]] = True
    return [np.flatnonzero(comp == c) for c in range(len(open_comp)) if not open_comp[c]]


def overlapping_shells(mesh, tolerance: float, *, samples: int = OVERLAP_SAMPLES) -> list[tuple[int, int, str]]:
    """Pairs of closed shells of ``mesh`` that cross each other or lie one inside the other.

    A shell's points (its vertices, then its triangles' centroids, at most ``samples``, evenly picked) are tested
    against every other closed shell whose box they reach: a point more than ``tolerance`` inside it is inside. Some
    points inside and some outside: their surfaces cross; all of them inside: it is nested. Shells that only touch
    (every point within the tolerance of the other's surface) are neither.

    The cleaned mesh turns every closed shell outward (:func:`recon.mesh.clean_mesh`), so a nested shell always has
    the same orientation as the shell around it: a hollow part's cavity is reported too (recon builds no cavities).

    Returns
    -------
    list of (i, j, kind)
        Component numbers (``mesh.component``) and ``"cross"`` or ``"inside"`` (``i`` lies inside ``j``).
    """
    shells = _closed_components(mesh)
    if len(shells) < 2:
        return []
    import trimesh  # here, past the one-shell case: it is 0.3 s of start-up for nothing there

    V, F = mesh.vertices, mesh.faces
    comp = np.asarray(mesh.component)
    boxes = np.array([[V[F[t]].reshape(-1, 3).min(axis=0), V[F[t]].reshape(-1, 3).max(axis=0)] for t in shells])
    found: dict[tuple[int, int], str] = {}
    for i, ti in enumerate(shells):
        pts = np.concatenate([V[np.unique(F[ti])], mesh.face_centroids[ti]])
        if len(pts) > samples:
            pts = pts[np.linspace(0, len(pts) - 1, samples).astype(np.int64)]
        for j, tj in enumerate(shells):
            if i == j or (min(i, j), max(i, j)) in found:
                continue
            lo, hi = boxes[j, 0] - tolerance, boxes[j, 1] + tolerance
            near = pts[((pts >= lo) & (pts <= hi)).all(axis=1)]
            if not len(near):
                continue
            other = trimesh.Trimesh(vertices=V, faces=F[tj], process=False)
            depth = trimesh.proximity.signed_distance(other, near)  # positive inside
            inside = int((depth > tolerance).sum())
            if not inside:
                continue
            kind = "inside" if inside == len(pts) else "cross"
            found[(min(i, j), max(i, j))] = kind
            log.info("closed shells %d and %d: %s (%d of %d points inside)", i, j, kind, inside, len(pts))
    key = {i: int(comp[t[0]]) for i, t in enumerate(shells)}
    out = []
    for (i, j), kind in sorted(found.items()):
        out.append((key[i], key[j], kind))
    return out


# --------------------------------------------------------------------------------------------------
# The rules
# --------------------------------------------------------------------------------------------------


def _solid_rule(validity: dict, open_mesh: bool, source: str) -> Rule:
    v = {k: validity.get(k) for k in ("shape_type", "valid", "closed", "free_edges", "volume")}
    if open_mesh:
        ok = bool(validity.get("valid")) and validity.get("shape_type") in ("shell", "compound") \
            and (validity.get("n_shells") or 0) > 0
        limit, what = "a valid shell (the mesh is open)", "a valid shell"
    else:
        solids = validity.get("shape_type") == "solid" or (
            validity.get("shape_type") == "compound" and (validity.get("n_solids") or 0) > 0
            and validity.get("n_shells") == validity.get("n_solids"))
        ok = bool(validity.get("valid") and validity.get("closed") and solids and (validity.get("volume") or 0) > 0)
        limit, what = "one valid closed solid", "a valid closed solid"
    detail = f"{source} holds {what}" if ok else (
        f"{source} does not hold {what}: {v['shape_type']}, valid={v['valid']}, closed={v['closed']}, "
        f"free edges={v['free_edges']}, volume={_g(v['volume'])}")
    return Rule("solid", ok, v, limit, (), detail)


def _coverage_rule(report: dict, labels: np.ndarray) -> Rule:
    faces = report["faces"]
    missing = [f["name"] for f in faces if f["status"] == "failed" or not f.get("built", True)]
    recorded = {f["part"] for f in faces}
    missing += [f"part_{p}" for p in np.unique(labels).tolist() if p not in recorded]
    detail = "every part of the mesh has a face" if not missing else (
        f"{len(missing)} parts of the mesh have no face: the result has holes there")
    return Rule("coverage", not missing, len(missing), 0, tuple(missing), detail)


def _count_rule(report: dict) -> Rule:
    open_count = report.get("exact_vertices", {}).get("open_count", [])
    if not open_count:
        return Rule("face_count", True, 0, 0, (), "the face count is proven (or found from the decomposition)")
    return Rule("face_count", False, len(open_count), 0, (), "; ".join(open_count))  # each says "face count not proven"


def _overlap_rule(mesh, labels: np.ndarray, report: dict, tolerance: float) -> Rule:
    pairs = overlapping_shells(mesh, tolerance)
    if not pairs:
        return Rule("overlap", True, 0, 0, (), "no closed shell of the mesh crosses or holds another")
    comps = {c for i, j, _ in pairs for c in (i, j)}
    comp = np.asarray(mesh.component)
    parts = set(np.unique(labels[np.isin(comp, list(comps))]).tolist())
    names = tuple(f["name"] for f in report["faces"] if f["part"] in parts)
    n_cross = sum(kind == "cross" for *_, kind in pairs)
    n_inside = len(pairs) - n_cross
    says = []
    if n_cross:
        says.append(f"the mesh holds {len({c for i, j, k in pairs if k == 'cross' for c in (i, j)})} overlapping "
                    "shells; recon does not rebuild their union")
    if n_inside:
        says.append(f"{n_inside} closed shell{'s lie' if n_inside > 1 else ' lies'} inside another; recon builds "
                    "every closed shell as a solid of its own (no cavities), so the solids overlap")
    return Rule("overlap", False, len(pairs), 0, names, "; ".join(says))


def _deviation_rules(report: dict, sag: np.ndarray, area: np.ndarray, labels: np.ndarray, pairs: np.ndarray,
                     tolerance: float, error: str | None) -> list[Rule]:
    dev = report.get("deviation")
    if dev is None:
        why = f"deviation could not be measured: {error}" if error else "deviation not measured (NOT verified)"
        return [Rule(name, False if error else None, None, None, (), why) for name in _DEVIATION_RULES]
    k, T = MAX_PER_TOLERANCE, tolerance
    m2s, s2m = dev["mesh_to_shape"], dev["shape_to_mesh"]
    sag95 = _weighted_percentile(sag, area, 95.0)  # the p95, as every other deviation rule judges
    rules = [_limit_rule("mesh_to_shape_p95", m2s.get("p95"), T, "mesh→shape p95"),
             _limit_rule("mesh_to_shape_max", m2s.get("max"), k * T, "mesh→shape max"),
             _limit_rule("shape_to_mesh_p95", s2m.get("p95"), T + sag95, "shape→mesh p95")]
    if sag95 > T:  # say what the limit holds: between its vertices the mesh pins the faces only to T + its sag
        rules[-1] = replace(rules[-1], detail=f"{rules[-1].detail} (T {_g(T)} mm + the mesh's chord sag {_g(sag95)} mm: "
                            "between its vertices the mesh does not pin the faces closer than that)")
    # Face by face: its largest distance from the mesh against k·T plus the largest sag of its triangles and of their
    # neighbours across its boundary: the face's edge lies on the true edge, off the mesh's polygon by the sag of the
    # curved face on the other side (a plane capping a coarse cylinder overhangs its polygon by the cylinder's sag).
    part_sag = np.zeros(int(labels.max()) + 1)
    np.maximum.at(part_sag, labels, sag)
    a, b = pairs[:, 0], pairs[:, 1]
    np.maximum.at(part_sag, labels[a], sag[b])
    np.maximum.at(part_sag, labels[b], sag[a])
    part_of = {f["name"]: f["part"] for f in report["faces"]}
    worst, bad = None, []
    for f in dev.get("faces", []):
        d = f.get("shape_to_mesh_max")
        p = part_of.get(f["name"])
        if d is None or p is None or p >= len(part_sag):
            continue
        limit = k * T + float(part_sag[p])
        if not d <= limit:
            bad.append(f["name"])
        if worst is None or d - limit > worst[0] - worst[1]:
            worst = (d, limit)
    if worst is None:  # no face measured: the global figure against the global limit
        worst = (s2m.get("max"), k * T + float(sag.max(initial=0.0)))
    value, limit = worst
    ok = bool(value is not None and np.isfinite(value) and not bad and value <= limit)
    rules.append(Rule("shape_to_mesh_max", ok, value, limit, tuple(bad),
                      _limit_words("shape→mesh max", value, limit, ok, bad)))
    return rules


def _limit_rule(name: str, value, limit: float, words: str) -> Rule:
    ok = bool(value is not None and np.isfinite(value) and value <= limit)
    return Rule(name, ok, value, limit, (), _limit_words(words, value, limit, ok, ()))


def _limit_words(words: str, value, limit, ok: bool, faces) -> str:
    at = f" at {', '.join(faces[:5])}{' …' if len(faces) > 5 else ''}" if faces else ""
    return f"{words} {_g(value)} mm {'≤' if ok else 'NOT ≤'} limit {_g(limit)} mm{at}"


def _volume_rule(validity: dict, mesh, sag: np.ndarray, tolerance: float, closed: bool) -> Rule:
    if not closed:
        return Rule("volume", None, None, None, (), "the mesh is open: it encloses no volume to compare")
    v_shape, v_mesh = validity.get("volume"), float(mesh.volume)
    limit = float(np.dot(mesh.face_areas, tolerance + sag))
    if v_shape is None or not np.isfinite(v_shape):
        return Rule("volume", False, None, limit, (), "the result has no volume")
    diff = abs(float(v_shape) - v_mesh)
    ok = diff <= limit
    detail = (f"volume {_g(v_shape)} mm³ vs the mesh's {_g(v_mesh)} mm³: off by {_g(diff)} mm³ "
              f"{'≤' if ok else 'NOT ≤'} limit {_g(limit)} mm³ (area × (T + sag))")
    return Rule("volume", ok, diff, limit, (), detail)


def _meshable_rule(unmeshed: list | None, source: str) -> Rule:
    # (short words: the batch summary's one line holds every failed rule; the settings are in unmeshed_faces' docs)
    if unmeshed is None:
        return Rule("meshable", None, None, None, (), "not checked")
    if not unmeshed:
        return Rule("meshable", True, None, None, (), f"every face of {source} meshes at FreeCAD's display settings")
    n = len(unmeshed)
    return Rule("meshable", False, None, None, tuple(unmeshed),
                f"{n} face{'s get' if n > 1 else ' gets'} no triangles at FreeCAD's display settings (a hole there)")


def unmeshed_names(shape, names) -> list[str]:
    """The names (``names``, in :func:`recon.brep._step_read.faces_of` order) of the faces of ``shape`` that get no
    triangles at FreeCAD's display settings (:func:`recon.brep._tessellate.unmeshed_faces`)."""
    from .brep._tessellate import unmeshed_faces

    t = time.perf_counter()
    out = [names[i] if i < len(names) else f"face_{i}" for i in unmeshed_faces(shape)]
    log.info("meshable: %d faces without triangles at FreeCAD's settings (%.3f s)", len(out), time.perf_counter() - t)
    return out


def _weighted_percentile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    if not len(values):
        return 0.0
    order = np.argsort(values)
    c = np.cumsum(weights[order])
    if c[-1] <= 0:
        return float(values.max())
    return float(values[order][min(np.searchsorted(c, q / 100.0 * c[-1]), len(c) - 1)])


def _g(x) -> str:
    return "n/a" if x is None else f"{x:.4g}"


def judge(report: dict, mesh, labels: np.ndarray, *, validity: dict | None = None, source: str = "the result",
          deviation_error: str | None = None, overlap: Rule | None = None) -> Verdict:
    """Check a conversion against every rule.

    Parameters
    ----------
    report : dict
        The conversion's report (``recon.pipeline``): tolerance, validity, faces with names and parts, deviation.
    mesh : recon.mesh.Mesh
    labels : (m,) int
        The face label (part) of every triangle of ``mesh``.
    validity : dict, optional
        The validity to judge the ``solid`` rule by (the written file's, :func:`read_back`); default the report's.
    source : str
        Where ``validity`` comes from, for the rule's words.
    deviation_error : str, optional
        Why the deviation could not be measured (its rules then fail); None with no deviation: not checked.
    overlap : Rule, optional
        The ``overlap`` rule already found for this mesh (it depends on the mesh alone).

    Returns
    -------
    Verdict
    """
    t = time.perf_counter()
    tolerance = float(report["tolerance"])
    validity = report["validity"] if validity is None else validity
    labels = np.asarray(labels)
    sag = _sag_of(mesh)
    solid, volume, meshable = _file_rules(validity, mesh, sag, tolerance, source,
                                          validity.get("unmeshed_faces", report.get("unmeshed_faces")))
    # (a defect of the shape, meshable comes before the figures: the summary names the first failed rules)
    rules = [solid, _coverage_rule(report, labels), meshable,
             overlap if overlap is not None else _overlap_rule(mesh, labels, report, tolerance)]
    rules += _deviation_rules(report, sag, mesh.face_areas, labels, mesh.face_adjacency, tolerance, deviation_error)
    rules += [volume, _count_rule(report)]
    verdict = Verdict(tuple(rules), time.perf_counter() - t)
    for r in verdict.failed:
        log.info("rule %s failed: %s", r.rule, r.detail)
    return verdict


# --------------------------------------------------------------------------------------------------
# The written file
# --------------------------------------------------------------------------------------------------


def read_back(path: str | os.PathLike) -> dict:
    """The validity of a written result, read back from disk (the report's ``validity`` keys).

    ``.step``/``.stp`` through OpenCascade's STEP reader, ``.igs``/``.iges`` its IGES reader, ``.brep`` BRepTools, ``.stl`` as a mesh (trimesh,
    vertices merged): closed when watertight, valid when consistently wound, with the volume it encloses. A B-rep
    file's ``unmeshed_faces`` are the names of its faces that get no triangles at FreeCAD's display settings (as a
    program that opens the file meshes it); an STL has none to list.
    """
    path = Path(path)
    if path.suffix.lower() != ".stl":
        from .brep import shape_validity
        from .brep._step_read import read_back_shape

        shape, names = read_back_shape(path)
        val = shape_validity(shape)
        return {"shape_type": val.shape_type, "valid": bool(val.valid), "closed": bool(val.closed),
                "free_edges": int(val.free_edges), "volume": float(val.volume), "n_solids": int(val.n_solids),
                "n_shells": int(val.n_shells), "unmeshed_faces": unmeshed_names(shape, names)}
    import trimesh

    tm = trimesh.load(str(path), force="mesh")
    edges = np.sort(tm.edges, axis=1)
    _, per_edge = np.unique(edges, axis=0, return_counts=True)
    watertight = bool(tm.is_watertight)
    bodies = len(tm.split(only_watertight=False)) if watertight else 0
    return {"shape_type": "solid" if watertight and bodies == 1 else ("compound" if watertight else "shell"),
            "valid": bool(tm.is_winding_consistent), "closed": watertight,
            "free_edges": int((per_edge == 1).sum()), "volume": float(tm.volume) if watertight else 0.0,
            "n_solids": bodies, "n_shells": max(bodies, 1)}


def write_checked(result, path: str | os.PathLike, *, name: str = "recon", units: str = "mm",
                  schema: str = "AP242") -> Verdict:
    """Write ``result``'s B-rep (:func:`recon.brep.write_shape`, with its ``units`` and ``schema``), read the file
    back and judge the ``solid``, ``volume`` and ``meshable`` rules on what it holds (an STL keeps the B-rep's
    ``meshable``: it holds no faces); ``result.report["verdict"]`` is updated and the new verdict returned."""
    from OCP.TopAbs import TopAbs_FACE

    from .brep import write_shape
    from .brep._export import model_units
    from .brep._result import collapsed_face_count, count_shapes
    from .errors import BrepError, ReconError, UnwritableError

    n_faces = count_shapes(result.brep.occ, TopAbs_FACE)
    if n_faces == collapsed_face_count(result.brep.occ):  # (nothing to write: no file, rather than an empty one)
        raise UnwritableError(f"the B-rep holds no face with area ({n_faces} faces bounded by degenerate edges only)"
                              if n_faces else "the B-rep holds no face")
    # an STL's chords within half the tolerance of the faces: the volume rule holds for the file as for the B-rep
    path = write_shape(path, result.brep, name=name, deflection=0.5 * float(result.report["tolerance"]),
                       units=units, schema=schema)
    old = result.verdict
    try:
        with model_units(units):  # read back in the mesh's unit, the rules' unit
            validity = read_back(path)
    except ReconError as err:  # what no CAD program could read either is not left behind as a result
        Path(path).unlink(missing_ok=True)
        # recon's B-rep, not the user's path: the file was written, what it holds is unreadable
        raise BrepError(f"the written {Path(path).name} could not be read back ({err}); it was removed") from err
    t = time.perf_counter()
    solid, volume, meshable = _file_rules(validity, result.mesh, _sag_of(result.mesh),
                                          float(result.report["tolerance"]), f"the written file {path.name}",
                                          validity.get("unmeshed_faces"))
    rules = (solid, volume) if "unmeshed_faces" not in validity else (solid, volume, meshable)
    verdict = replace(old.with_rules(*rules), seconds=old.seconds + time.perf_counter() - t)
    result.report["verdict"] = verdict.to_json()
    return verdict


def schema() -> dict:
    """The JSON Schema of ``recon convert``'s report (``recon/report.schema.json``)."""
    return json.loads((Path(__file__).parent / "report.schema.json").read_text())
