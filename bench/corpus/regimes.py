"""Tessellation regimes of the corpus: how a user's mesh of a corpus part looks, with the true face of every triangle.

``tessellate(solid, regime, seed) -> (vertices, faces, true_face_per_triangle)``; every regime parameter is drawn
from ``default_rng([seed, REGIME_CODE[regime]])``, and no choice is made on BLAS or numpy SIMD results (their last
bit depends on the CPU), so a (seed, regime) pair is one mesh on every x86 machine with AVX2 (bench/scan.md "s40-det").

- ``export``: OpenCascade's tessellation (``BRepMesh_IncrementalMesh``) at STL-export settings: chord deviation
  0.01–1 % of the diagonal (log-uniform), angle 0.1–0.8 rad; per-face triangulations welded at their shared edge
  nodes (closed by construction; checked); vertices exactly on the faces.
- ``export-obj``: the same mesh as an OBJ whose planar faces are convex polygons (:func:`planar_polygons`).
- ``fine``: scan-like isotropic triangles with no noise, 20k–300k triangles (the fixtures' regime): the fixtures'
  remesher at ≤ 1,000 triangles, then 1:4 subdivisions with every new vertex projected onto its face/edge.
- ``scanNN``: dense (30k–300k triangles), uneven (edges on curved faces 1/2–1/3 as long as on planes), Gaussian noise
  along the vertex normals with σ = 0.05 / 0.1 / 0.2 / 0.5 % of the diagonal (``scan05``/``scan10``/``scan20``/
  ``scan50``); ``scan10-holes``: σ = 0.1 % and 1–3 % of the area removed in 2–4 patches (an occluded scan);
  ``scan10-outliers``: σ = 0.1 % and 0.1 % of the vertices displaced by 1–2 % of the diagonal in random directions.

The mesh functions (OCC tessellation and welding, remeshing, subdivision, noise) are the fixtures generator's
(``fixtures/make_fixtures.py``), imported, not copied.
"""

from __future__ import annotations

import importlib.util
import math
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

#: fixed integer per regime for the regime's random stream (never ``hash(name)``: it is salted per process)
REGIME_CODE = {"export": 1, "export-obj": 1, "fine": 2, "scan05": 3, "scan10": 4, "scan20": 5, "scan50": 6,
               "scan10-holes": 7, "scan10-outliers": 8}
REGIMES = tuple(REGIME_CODE)
#: noise σ of each scan regime, a fraction of the diagonal (issue 23)
SCAN_SIGMA = {"scan05": 0.0005, "scan10": 0.001, "scan20": 0.002, "scan50": 0.005, "scan10-holes": 0.001,
              "scan10-outliers": 0.001}
#: triangle-count ranges (issue 22: fine 20k–300k; issue 23: scans 30k–300k)
FINE_RANGE = (20_000, 300_000)
SCAN_RANGE = (30_000, 300_000)
#: the remesher (pure Python, ~0.05 s a triangle) works at most this many triangles; subdivision takes it to the target
REMESH_MAX = 1_000
#: remeshes tried to hit the remesher's target, and the ratio to it that is close enough (a subdivision is 4×)
REMESH_TRIES = 3
REMESH_SLACK = 1.25
#: the coarsest remesh tried, in the first edge length h₀ (see :func:`_dense`)
REMESH_COARSEST = 2.0
#: a remeshed mesh is the part when no vertex lies farther than this many of its plane edges h from it: every vertex is
#: projected onto its face's surface, so honest meshes miss by chord and projection error only (≤ 0.32 h on scan10
#: seeds 1–7); a face triangle whose edge chords across a hole smaller than the coarse remesh's edge is projected onto
#: the face's untrimmed surface, a membrane over the hole (scan10 seed 0: 3.7 h, bench/scan.md "s39-rim")
OFF_PART_EDGES = 1.0


def make_fixtures():
    """The fixtures generator as a module (a script, not a package: loaded by path once)."""
    name = "recon_make_fixtures"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "fixtures" / "make_fixtures.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def regime_rng(seed: int, regime: str):
    return np.random.default_rng([int(seed), REGIME_CODE[regime]])


def _norm3(d) -> float:
    """|d| of a 3-vector without BLAS (np.linalg.norm's last bit depends on the CPU's kernel): the remesher's."""
    return make_fixtures()._norm(d)


def diagonal(vertices) -> float:
    return _norm3(vertices.max(axis=0) - vertices.min(axis=0))


def export_settings(seed: int) -> tuple[float, float]:
    """(chord deviation as a fraction of the diagonal, angular deflection in rad) of ``export``."""
    rng = regime_rng(seed, "export")
    return float(10 ** rng.uniform(-4, -2)), float(rng.uniform(0.1, 0.8))


def _export(solid, seed):
    mf = make_fixtures()
    chord, angle = export_settings(seed)
    bb = solid.bounding_box()
    diag = math.dist((bb.min.X, bb.min.Y, bb.min.Z), (bb.max.X, bb.max.Y, bb.max.Z))
    v, t, lab = mf.occ_mesh(solid, deflection=chord * diag, angular=angle)[:3]
    return v, t, lab, {"chord": chord, "angle": angle}


def _curved(table):
    return np.array([e["type"] != "plane" for e in table])


def subdivisions(remeshed: int, target: int, bounds: tuple[int, int]) -> int:
    """How many 1:4 subdivisions take a remeshed mesh of ``remeshed`` triangles nearest ``target`` (in ratio) while
    staying inside ``bounds``: each one multiplies the count by exactly 4, so the count is known before subdividing.

    The remesher cannot always hit its own target (it never collapses a feature edge, so parts with many small faces
    keep more triangles): the subdivisions are chosen on the count it made, not on the one asked for."""
    lo, hi = bounds
    if remeshed < 1 or hi < 4 * lo:
        raise ValueError("bounds must span a factor 4 (one subdivision) and the mesh have a triangle")
    # with hi ≥ 4 lo some k lands inside the bounds whenever remeshed ≤ hi; a coarser remesh is kept as it is
    ks = [k for k in range(0, 16) if lo <= remeshed * 4**k <= hi] or [0]
    return min(ks, key=lambda k: ratio_off(remeshed * 4**k, target))


def ratio_off(count: int, target: int) -> Fraction:
    """How far ``count`` is from ``target``, exactly: max(count/target, target/count) (|log| of the ratio, ordered
    the same). Integers, not logarithms: a count exactly twice and another half the target tie on every machine,
    and the first wins; a logarithm's last bit (libm's, per CPU variant) would pick one."""
    return max(Fraction(count, target), Fraction(target, count))


def _dense(solid, target, bounds, *, size=None):
    """A scan-like mesh of about ``target`` triangles inside ``bounds``: remeshed at ≤ REMESH_MAX triangles, then
    subdivided 1:4 (:func:`subdivisions`).

    The remesher overshoots its own target where feature edges are short (it keeps every corner, and a small face
    needs triangles of its own), and the subdivisions multiply that: its edge length is corrected from the count it
    made (a count goes as 1/h²) at most REMESH_TRIES times, and the remesh whose final count is nearest the target
    kept."""
    mf = make_fixtures()
    table = mf.face_table(solid)
    area = sum(e["area"] for e in table)
    k0 = next(k for k in range(16) if REMESH_MAX * 4**k >= target)  # in integers: a ceil(log) flips on a last bit
    want = target / 4**k0
    # with uneven sizes the same h gives more triangles: scale h by the area-weighted mean density
    density = 1.0 if size is None else float(sum(e["area"] / s**2 for e, s in zip(table, size)) / area)
    h = h0 = mf.h_for(area * density, want)
    best = None
    for _ in range(REMESH_TRIES):
        remeshed = mf.scanlike_mesh(solid, table, h, size=size)
        n = len(remeshed[1])
        k = subdivisions(n, target, bounds)
        miss = ratio_off(n * 4**k, target)
        if best is None or miss < best[0]:
            best = (miss, remeshed, k, h)
        if ratio_off(n * 4**k0, target) <= Fraction(REMESH_SLACK):
            break
        # never coarser than 2 h₀ (a quarter of the triangles: one subdivision fewer does that exactly); coarser
        # it can run away (scan20 seed 1, a 46-face blended part, at 2.3 h₀: out of 4 GiB after 20 min)
        h, last = min(h * math.sqrt(n / want), REMESH_COARSEST * h0), h
        if h == last:
            break
    _, (v, t, lab, kind, owner, feature, fproj, eproj), k, h = best
    mesh = (v, t, lab, kind, owner, feature)
    for _ in range(k):
        mesh = mf.subdivide(*mesh, fproj, eproj)
    off = off_part(solid, mesh[0]) / (h / 2**k)
    if off > OFF_PART_EDGES:
        raise MeshNotPart(f"the remeshed mesh is not the part: a vertex {off:.2f} edges h off it (> {OFF_PART_EDGES}; the "
                          f"coarse remesh of {len(t)} triangles at h {h:.3g} bridges a feature smaller than its edge)")
    return mesh[0], mesh[1], mesh[2], table, h / 2**k, len(t)


class MeshNotPart(ValueError):
    """The generator's mesh has vertices off the true part (a membrane over a hole): not a mesh of the part."""


def off_part(solid, vertices) -> float:
    """The largest distance of ``vertices`` to the faces of ``solid`` (a build123d or OCP shape)."""
    from recon.brep._distance import BrepDistance

    shape = getattr(solid, "wrapped", solid)
    d = np.abs(BrepDistance(shape, rng=np.random.default_rng(0)).signed_distance(np.asarray(vertices, float))[0])
    return float(np.nanmax(d)) if np.isfinite(d).any() else float("nan")


def _fine(solid, seed):
    rng = regime_rng(seed, "fine")
    # math.log10, not np.log10: numpy runs AVX-512 code on AVX-512 CPUs (1.7 % of its values differ in the last bit)
    target = int(10 ** rng.uniform(math.log10(FINE_RANGE[0]), math.log10(FINE_RANGE[1])))
    v, t, lab, _, h, remeshed = _dense(solid, target, FINE_RANGE)
    return v, t, lab, {"target": target, "h": h, "remeshed": remeshed}


def _scan(solid, seed, regime):
    mf = make_fixtures()
    rng = regime_rng(seed, regime)
    # math.log10, not np.log10 (see _fine)
    target = int(10 ** rng.uniform(math.log10(SCAN_RANGE[0]), math.log10(SCAN_RANGE[1])))
    ratio = float(rng.uniform(2, 3))  # curved faces sampled 2–3 times as densely (along an edge) as planes
    table = mf.face_table(solid)
    v, t, lab, _, h, remeshed = _dense(solid, target, SCAN_RANGE, size=np.where(_curved(table), 1.0 / ratio, 1.0))
    diag = diagonal(v)
    info = {"target": target, "curved_ratio": ratio, "h_plane": h, "remeshed": remeshed,
            "sigma": SCAN_SIGMA[regime] * diag}
    v = mf.noisy(v, t, info["sigma"], rng)
    if regime.endswith("-holes"):
        keep = _hole_patches(v, t, rng, share=float(rng.uniform(0.01, 0.03)), count=int(rng.integers(2, 5)))
        info["removed_triangles"] = int((~keep).sum())
        t, lab = t[keep], lab[keep]
        used = np.unique(t)  # vertices of removed triangles only: drop them
        remap = np.full(len(v), -1)
        remap[used] = np.arange(len(used))
        v, t = v[used], remap[t]
    if regime.endswith("-outliers"):
        n = max(1, int(round(0.001 * len(v))))
        idx = rng.choice(len(v), n, replace=False)
        d = rng.standard_normal((n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        v = v.copy()
        v[idx] += d * rng.uniform(0.01, 0.02, n)[:, None] * diag
        info["outliers"] = n
    return v, t, lab, info


def _hole_patches(v, t, rng, *, share, count):
    """Mask of the triangles kept after removing ``count`` patches grown by adjacency from random triangles until
    they hold ``share`` of the area."""
    from scipy.sparse import coo_matrix

    area = 0.5 * np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]), axis=1)
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, inv = np.unique(edges, axis=0, return_inverse=True)
    tri = np.tile(np.arange(len(t)), 3)
    inc = coo_matrix((np.ones(len(tri)), (tri, inv.ravel()))).tocsr()
    adj = (inc @ inc.T).tocsr()  # triangles sharing an edge
    removed = np.zeros(len(t), bool)
    budget = share * area.sum() / count
    for start in rng.choice(len(t), count, replace=False):
        front, got = [int(start)], 0.0
        while front and got < budget:
            nxt = []
            for f in front:
                if not removed[f] and got < budget:
                    removed[f] = True
                    got += area[f]
                    nxt.extend(int(x) for x in adj.indices[adj.indptr[f]:adj.indptr[f + 1]] if not removed[x])
            front = sorted(set(nxt))
    return ~removed


def tessellate_info(solid, regime: str, seed: int):
    """:func:`tessellate` plus a dict of the regime's drawn parameters."""
    if regime not in REGIME_CODE:
        raise ValueError(f"regime: expected one of {', '.join(REGIMES)}, got {regime!r}")
    if regime in ("export", "export-obj"):
        v, t, lab, info = _export(solid, seed)
    elif regime == "fine":
        v, t, lab, info = _fine(solid, seed)
    else:
        v, t, lab, info = _scan(solid, seed, regime)
    return np.asarray(v, float), np.asarray(t, np.int64), np.asarray(lab, np.int64), info


def tessellate(solid, regime: str, seed: int):
    """``(vertices (n, 3) float, faces (m, 3) int, true_face_per_triangle (m,) int)`` of ``solid`` in ``regime``."""
    return tessellate_info(solid, regime, seed)[:3]


def is_watertight(faces) -> bool:
    """Every edge in exactly two triangles, once in each direction (closed, manifold, consistently oriented)."""
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    und = np.sort(directed, axis=1)
    _, counts = np.unique(und, axis=0, return_counts=True)
    _, dcounts = np.unique(directed, axis=0, return_counts=True)
    return bool(len(faces) and (counts == 2).all() and (dcounts == 1).all())


# ----------------------------------------------------------------------------------------------------------------------
# Planar faces as convex polygons (an OBJ as CAD programs write it)


def planar_polygons(vertices, faces, labels, planar):
    """Merge the triangles of each planar true face into convex polygons; other triangles stay triangles.

    Greedy: two polygons of one planar face sharing an edge merge when the union is still convex (every reader
    fan-triangulates a convex polygon into the same surface). Returns ``(polygons, polygon_labels)``: a list
    of vertex-index loops, outward oriented like the triangles.
    """
    polys, plabels = [], []
    for fi in range(int(labels.max()) + 1 if len(labels) else 0):
        tri = faces[labels == fi]
        if not len(tri):
            continue
        if not planar[fi]:
            polys.extend(list(map(int, x)) for x in tri)
            plabels.extend([fi] * len(tri))
            continue
        normal = np.cross(vertices[tri[:, 1]] - vertices[tri[:, 0]], vertices[tri[:, 2]] - vertices[tri[:, 0]]).sum(0)
        for loop in _merge_convex(vertices, [list(map(int, x)) for x in tri], normal / _norm3(normal)):
            polys.append(loop)
            plabels.append(fi)
    return polys, np.array(plabels, dtype=np.int64)


def _merge_convex(vertices, loops, normal):
    alive = dict(enumerate(loops))
    changed = True
    while changed:
        changed = False
        owner = {}
        for pid in sorted(alive):
            loop = alive[pid]
            for a, b in zip(loop, loop[1:] + loop[:1]):
                owner[(a, b)] = pid
        for (a, b), pid in sorted(owner.items()):
            other = owner.get((b, a))
            if other is None or other == pid or pid not in alive or other not in alive:
                continue
            merged = _join(alive[pid], alive[other], a, b)
            if merged is not None and _convex(vertices, merged, normal):
                alive[pid] = merged
                del alive[other]
                changed = True
    return [alive[k] for k in sorted(alive)]


def _join(p, q, a, b):
    """The loop of ``p`` (with edge a→b) and ``q`` (with edge b→a) glued along that edge, or None."""
    i, j = p.index(a), q.index(b)
    p_rot = p[i + 1:] + p[:i + 1]  # ... ends with a, starts after a (with b)
    q_rot = q[j + 1:] + q[:j + 1]  # starts after b (with a), ends with b
    if p_rot[0] != b or q_rot[0] != a:
        return None
    loop = p_rot + q_rot[1:-1]  # b ... a, then q's vertices between a and b
    return loop if len(set(loop)) == len(loop) else None


def _convex(vertices, loop, normal):
    """No reflex corner (collinear boundary nodes allowed: OCC puts edge nodes on straight edges too)."""
    p = vertices[loop]
    e = np.roll(p, -1, axis=0) - p
    c = np.cross(e, np.roll(e, -1, axis=0))
    turn = c[:, 0] * normal[0] + c[:, 1] * normal[1] + c[:, 2] * normal[2]  # not `@`: BLAS rounds per CPU kernel
    scale = np.linalg.norm(e, axis=1) * np.linalg.norm(np.roll(e, -1, axis=0), axis=1)
    return bool((turn > -1e-9 * scale).all())


def write_obj(path, vertices, polygons) -> None:
    """Write an OBJ of ``polygons`` (vertex-index loops) with vertices at full double precision."""
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]
    lines += ["f " + " ".join(str(i + 1) for i in loop) for loop in polygons]
    Path(path).write_text("\n".join(lines) + "\n")
