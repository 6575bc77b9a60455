"""Seeded random CAD parts for the corpus: ``part(seed) -> (solid, meta)``.

Every random number comes from ``numpy.random.default_rng(seed)`` in a fixed order; shapes are built with build123d
(OpenCascade) whose topology order is deterministic for the same operations, so a seed gives the same part on every
machine. A feature that OpenCascade cannot build (a fillet larger than its faces allow, a cut that leaves two
solids) is retried at half its size, then dropped; both are recorded in ``meta["dropped"]``.

Families (picked by the seed): prismatic blocks with holes, pockets, bosses, ribs and edge blends; turned parts
(revolved profiles with tori, cones, bolt circles); lofts (B-spline walls); sweeps along splines; blended blocks
(every edge filleted, so three fillets meet at each corner, plus a variable-radius fillet); single primitives.
"""

from __future__ import annotations

import math

import numpy as np

#: most true faces a part may have (issue 22: 1–150); a feature that would exceed it is dropped
MAX_FACES = 150
#: halvings tried before a failing feature is dropped
RETRIES = 2
#: surface types recon can make; every other OCC type (extrusion, revolution, offset) is free-form
RECON_TYPES = ("plane", "cylinder", "cone", "sphere", "torus", "bspline")


class _Builder:
    """The part under construction: applies features, validates each result, records what was done."""

    def __init__(self, rng, solid, family):
        self.rng = rng
        self.solid = solid
        self.meta = {"family": family, "ops": [], "dropped": [], "traits": []}

    def size(self):
        bb = self.solid.bounding_box()
        return np.array([bb.max.X - bb.min.X, bb.max.Y - bb.min.Y, bb.max.Z - bb.min.Z])

    def top(self):
        return float(self.solid.bounding_box().max.Z)

    def bottom(self):
        return float(self.solid.bounding_box().min.Z)

    def apply(self, name, make, scale=1.0, trait=None):
        """Try ``make(scale)`` (a function returning the new shape), halving ``scale`` on failure; keep the first
        result that is one valid solid with at most MAX_FACES faces and a volume that changed."""
        for attempt in range(RETRIES + 1):
            s = scale * 0.5**attempt
            try:
                shape = make(s)
                solids = shape.solids()
                if len(solids) != 1:
                    raise ValueError(f"{len(solids)} solids")
                new = solids[0]
                if not new.is_valid:
                    raise ValueError("invalid")
                if len(new.faces()) > MAX_FACES:
                    self.meta["dropped"].append(f"{name}: over {MAX_FACES} faces")
                    return False
                if abs(new.volume - self.solid.volume) < 1e-9 * self.solid.volume and name != "fillet_var":
                    raise ValueError("no change")
            except Exception as err:  # an OpenCascade failure is an outcome of a random feature: retry smaller
                last = f"{type(err).__name__}: {err}"[:80]
                continue
            self.solid = new
            self.meta["ops"].append(f"{name}@{s:.3g}" if attempt else name)
            if trait and trait not in self.meta["traits"]:
                self.meta["traits"].append(trait)
            return True
        self.meta["dropped"].append(f"{name}: {last}")
        return False

    def point_on_top(self, margin):
        """A random (x, y) inside the part's top footprint, ``margin`` (fraction of the size) from its sides."""
        sx, sy, _ = self.size()
        bb = self.solid.bounding_box()
        cx, cy = 0.5 * (bb.min.X + bb.max.X), 0.5 * (bb.min.Y + bb.max.Y)
        u, v = self.rng.uniform(-0.5 + margin, 0.5 - margin, 2)
        return float(cx + u * sx), float(cy + v * sy)


# ----------------------------------------------------------------------------------------------------------------------
# Sketches and bases


def _sketch(rng, w, d):
    """A random closed sketch about the origin of about ``w`` × ``d``: rectangle, polygon, slot, circle or n-gon."""
    from build123d import Circle, Polygon, Rectangle, RegularPolygon, SlotOverall

    kind = ["rectangle", "regular", "slot", "circle", "polygon"][int(rng.integers(5))]
    if kind == "rectangle":
        return kind, Rectangle(w, d)
    if kind == "regular":
        return kind, RegularPolygon(0.5 * w, int(rng.integers(5, 9)))
    if kind == "slot":
        return kind, SlotOverall(w, min(d, 0.8 * w))
    if kind == "circle":
        return kind, Circle(0.5 * w)
    n = int(rng.integers(4, 8))  # a convex polygon: sorted angles on an ellipse
    angles = np.sort(rng.uniform(0, 2 * math.pi, n) + np.arange(n) * 2 * math.pi / n) % (2 * math.pi)
    angles = np.sort(angles)
    pts = [(float(0.5 * w * math.cos(a)), float(0.5 * d * math.sin(a))) for a in angles]
    return kind, Polygon(*pts)


def _base_prismatic(rng):
    from build123d import extrude

    w = float(rng.uniform(30, 120))
    d = float(w * rng.uniform(0.4, 1.0))
    h = float(w * rng.choice([rng.uniform(0.05, 0.12), rng.uniform(0.15, 0.6)]))  # plates and blocks
    kind, sk = _sketch(rng, w, d)
    return extrude(sk, h), f"extrude {kind} {w:.0f}x{d:.0f}x{h:.0f}"


def _base_revolved(rng):
    """A turned profile: steps of cylinders and cones, optionally a concave arc, revolved about Z."""
    from build123d import Axis, BuildLine, BuildPart, BuildSketch, Plane, Polyline, make_face, revolve

    n = int(rng.integers(2, 6))
    radii = rng.uniform(8, 40, n)
    z = np.concatenate([[0.0], np.cumsum(rng.uniform(4, 20, n))])
    pts = [(0.0, 0.0)]
    for i in range(n):
        r = float(radii[i])
        taper = rng.uniform() < 0.35  # a cone instead of a step
        pts.append((r, float(z[i])))
        nxt = float(radii[i + 1]) if taper and i + 1 < n else r
        pts.append((nxt, float(z[i + 1])))
    pts.append((0.0, float(z[-1])))
    clean = [pts[0]]
    for p in pts[1:]:
        if math.dist(p, clean[-1]) > 1e-6:
            clean.append(p)
    with BuildPart() as bp:
        with BuildSketch(Plane.XZ):
            with BuildLine():
                Polyline(*clean, close=True)
            make_face()
        revolve(axis=Axis.Z)
    return bp.part, f"revolve {n} steps"


def _base_lofted(rng):
    from build123d import Circle, Ellipse, Plane, Pos, Rectangle, Rot, fillet, loft

    n = int(rng.integers(2, 4))
    sections, z = [], 0.0
    for i in range(n):
        a, b = rng.uniform(10, 35, 2)
        kind = int(rng.integers(3))
        if kind == 0:
            sk = Ellipse(float(max(a, b)), float(min(a, b)))
        elif kind == 1:
            sk = Circle(float(a))
        else:
            sk = fillet(Rectangle(float(2 * a), float(2 * b)).vertices(), radius=float(0.3 * min(a, b)))
        off = rng.uniform(-5, 5, 2)
        sections.append(Plane.XY.offset(z) * Pos(float(off[0]), float(off[1])) * Rot(0, 0, float(rng.uniform(0, 40)))
                        * sk)
        z += float(rng.uniform(15, 40))
    return loft(sections), f"loft {n} sections"


def _base_swept(rng):
    from build123d import Circle, Plane, Rectangle, Spline, sweep

    n = int(rng.integers(3, 5))
    pts = [(0.0, 0.0, 0.0)]
    for _ in range(n - 1):
        step = rng.uniform([-25, -25, 15], [25, 25, 35])
        pts.append(tuple(float(a + b) for a, b in zip(pts[-1], step)))
    path = Spline(*pts, tangents=[(0, 0, 1), tuple(float(x) for x in rng.uniform([-1, -1, 0.2], [1, 1, 1]))])
    r = float(rng.uniform(3, 8))
    prof = Circle(r) if rng.uniform() < 0.5 else Rectangle(2 * r, 1.4 * r)
    return sweep(Plane.XY * prof, path), f"sweep along a {n}-point spline"


def _base_primitive(rng):
    from build123d import Cone, Cylinder, Sphere, Torus

    k = int(rng.integers(4))
    r = float(rng.uniform(10, 40))
    if k == 0:
        return Sphere(r), "sphere"
    if k == 1:
        return Torus(r, float(r * rng.uniform(0.15, 0.45))), "torus"
    if k == 2:
        return Cylinder(r, float(r * rng.uniform(0.3, 3))), "cylinder"
    return Cone(r, float(r * rng.uniform(0, 0.7)), float(r * rng.uniform(0.5, 2))), "cone"


# ----------------------------------------------------------------------------------------------------------------------
# Features (each draws its own numbers, then hands ``make(scale)`` to the builder)


def _edges_at(solid, z, axis_parallel=None):
    """Edges lying in the plane Z = ``z`` (within a relative 1e-6), or, with ``axis_parallel``, the straight edges
    parallel to Z."""
    from build123d import Axis, GeomType

    span = max(solid.bounding_box().size.Z, 1.0)
    if axis_parallel:
        return [e for e in solid.edges().filter_by(Axis.Z) if e.geom_type == GeomType.LINE]
    return [e for e in solid.edges() if abs(e.bounding_box().min.Z - z) < 1e-6 * span
            and abs(e.bounding_box().max.Z - z) < 1e-6 * span]


def _holes(b, rng):
    """Through, blind or counterbored holes from the top: one, a row, or a grid (a part with many holes)."""
    from build123d import Cylinder, Pos

    sx, sy, sz = b.size()
    kind = ["through", "blind", "counterbore"][int(rng.integers(3))]
    pattern = ["single", "row", "grid"][int(rng.integers(3))]
    counts = {"single": (1, 1), "row": (int(rng.integers(2, 7)), 1), "grid": tuple(int(k) for k in rng.integers(2, 6, 2))}
    nx, ny = counts[pattern]
    pitch = min(sx / (nx + 1), sy / (ny + 1))
    r = float(pitch * rng.uniform(0.12, 0.35))
    top, bottom = b.top(), b.bottom()
    depth = float((top - bottom) * rng.uniform(0.3, 0.8))
    bb = b.solid.bounding_box()
    cx, cy = 0.5 * (bb.min.X + bb.max.X), 0.5 * (bb.min.Y + bb.max.Y)
    centres = [(cx + (i - (nx - 1) / 2) * pitch, cy + (j - (ny - 1) / 2) * pitch) for i in range(nx) for j in range(ny)]

    def make(s):
        part = b.solid
        rr = r * s
        for x, y in centres:
            if kind == "through":
                tool = Pos(x, y, 0.5 * (top + bottom)) * Cylinder(rr, 1.2 * (top - bottom))
            elif kind == "blind":
                tool = Pos(x, y, top - 0.5 * depth + 0.5 * rr) * Cylinder(rr, depth + rr)
            else:
                cb = min(0.3 * (top - bottom), 2 * rr)
                tool = Pos(x, y, 0.5 * (top + bottom)) * Cylinder(rr, 1.2 * (top - bottom))
                tool += Pos(x, y, top - 0.5 * cb + 0.25 * cb) * Cylinder(1.7 * rr, 1.5 * cb)
            part = part - tool
        return part

    trait = "many_holes" if nx * ny >= 6 else None
    return b.apply(f"holes {kind} {pattern} {nx}x{ny}", make, trait=trait)


def _pocket(b, rng):
    """A rectangular or slot pocket from the top, its walls rounded (a tangent chain of planes and cylinders)."""
    from build123d import Pos, Rectangle, SlotOverall, extrude, fillet

    sx, sy, _ = b.size()
    w, d = float(sx * rng.uniform(0.2, 0.5)), float(sy * rng.uniform(0.2, 0.5))
    depth = float((b.top() - b.bottom()) * rng.uniform(0.2, 0.6))
    x, y = b.point_on_top(0.3)
    slot = rng.uniform() < 0.3
    corner = float(rng.uniform(0.1, 0.3))
    floor = float(rng.uniform(0.0, 0.4))

    def make(s):
        if slot:
            sk = SlotOverall(max(w, d), min(w, d))
        else:
            sk = fillet(Rectangle(w, d).vertices(), radius=corner * min(w, d) * s)
        tool = Pos(x, y, b.top() - depth) * extrude(sk, depth * 1.5)
        part = b.solid - tool
        edges = [e for e in _edges_at(part, b.top() - depth) if e.center().Z < b.top() - 1e-6]
        if floor > 0 and edges:  # round the pocket's floor: fillets chained tangentially around it
            part = fillet(edges, radius=floor * depth * s)
        return part

    return b.apply("pocket slot" if slot else "pocket", make, trait="tangent_chain")


def _boss(b, rng):
    from build123d import Box, Cylinder, Pos, fillet

    sx, sy, sz = b.size()
    r = float(min(sx, sy) * rng.uniform(0.08, 0.2))
    h = float(max(sz, 5.0) * rng.uniform(0.3, 1.0))
    x, y = b.point_on_top(0.25)
    round_ = rng.uniform() < 0.5
    box = rng.uniform() < 0.3
    rf = float(rng.uniform(0.1, 0.4))

    def make(s):
        tool = Pos(x, y, b.top() + 0.5 * h - 1e-3 * h) * (Box(2 * r, 2 * r, h) if box else Cylinder(r, h))
        part = b.solid + tool
        if round_:
            part = fillet(_edges_at(part, b.top() + h - 1e-3 * h), radius=rf * r * s)
        return part

    return b.apply("boss", make)


def _rib(b, rng):
    """A thin wall standing on the top face (thin walls are what the fixtures lack)."""
    from build123d import Box, Pos, Rot

    sx, sy, sz = b.size()
    t = float(min(sx, sy) * rng.uniform(0.015, 0.05))
    length = float(max(sx, sy) * rng.uniform(0.3, 0.7))
    h = float(max(sz, 5.0) * rng.uniform(0.4, 1.2))
    x, y = b.point_on_top(0.3)
    angle = float(rng.choice([0.0, 90.0, rng.uniform(0, 180)]))

    def make(s):
        return b.solid + Pos(x, y, b.top() + 0.5 * h * s - 1e-3 * h) * Rot(0, 0, angle) * Box(length, t, h * s)

    return b.apply("rib", make, trait="thin_wall")


def _shell(b, rng):
    """Hollow the part, open at the top: walls 1.5–5 % of its smallest size."""
    from build123d import Axis

    t = float(min(b.size()) * rng.uniform(0.015, 0.05))

    def make(s):
        top = b.solid.faces().sort_by(Axis.Z)[-1]
        return b.solid.offset_3d([top], -t * (1 + s) / 2)

    return b.apply("shell", make, trait="thin_wall")


def _blend(b, rng, which):
    """Fillet or chamfer a set of edges: the vertical ones, the top ones, all of them, or one tiny chamfer."""
    from build123d import chamfer, fillet

    edges = {"vertical": _edges_at(b.solid, 0, axis_parallel=True), "top": _edges_at(b.solid, b.top()),
             "all": list(b.solid.edges()), "tiny": list(b.solid.edges())}[which if which != "all_chamfer" else "all"]
    if not edges:
        return False
    if which == "tiny":  # a face 1:1000 of its neighbours: a chamfer of 0.1–0.3 % of the part on one edge
        edges = [edges[int(rng.integers(len(edges)))]]
        size, op, trait = float(max(b.size()) * rng.uniform(0.001, 0.003)), chamfer, "small_face"
    else:
        size = float(min(b.size()) * rng.uniform(0.03, 0.15))
        op = chamfer if (rng.uniform() < 0.35 or which == "all_chamfer") else fillet
        trait = "corner_blend" if which == "all" and op is fillet else None
    kw = "length" if op is chamfer else "radius"
    return b.apply(f"{op.__name__} {which} {len(edges)}", lambda s: op(edges, **{kw: size * s}), trait=trait)


def _variable_fillet(b, rng):
    """A fillet whose radius runs linearly from r1 to r2 along a straight edge (BRepFilletAPI_MakeFillet)."""
    from build123d import GeomType, Solid
    from OCP.BRepFilletAPI import BRepFilletAPI_MakeFillet

    lines = [e for e in b.solid.edges() if e.geom_type == GeomType.LINE]
    if not lines:
        return False
    edge = lines[int(rng.integers(len(lines)))]
    r1, r2 = (float(min(b.size()) * x) for x in rng.uniform(0.02, 0.12, 2))

    def make(s):
        mk = BRepFilletAPI_MakeFillet(b.solid.wrapped)
        mk.Add(r1 * s, r2 * s, edge.wrapped)
        mk.Build()
        if not mk.IsDone():
            raise ValueError("BRepFilletAPI_MakeFillet failed")
        return Solid(mk.Shape())

    return b.apply("fillet_var", make, trait="variable_fillet")


def _bolt_circle(b, rng):
    """Holes through a turned part's bottom flange on a circle (many holes on a revolved part)."""
    from build123d import Cylinder, Pos

    sx = b.size()[0]
    n = int(rng.integers(3, 13))
    rc = float(0.5 * sx * rng.uniform(0.55, 0.8))
    r = float(min(0.8 * rc * math.pi / n, 0.1 * sx) * rng.uniform(0.3, 0.6))
    h = float(b.size()[2])

    def make(s):
        part = b.solid
        for k in range(n):
            a = 2 * math.pi * k / n
            part = part - Pos(rc * math.cos(a), rc * math.sin(a), b.bottom() + 0.5 * h) * Cylinder(r * s, 1.2 * h)
        return part

    return b.apply(f"bolt circle {n}", make, trait="many_holes" if n >= 6 else None)


def _round_circles(b, rng):
    """Fillet a random subset of a turned part's circular edges (tori; neighbours make a tangent chain)."""
    from build123d import GeomType, fillet

    circles = [e for e in b.solid.edges() if e.geom_type == GeomType.CIRCLE]
    if not circles:
        return False
    pick = [e for e in circles if rng.uniform() < 0.5] or circles[:1]
    r = float(min(b.size()) * rng.uniform(0.02, 0.08))
    return b.apply(f"fillet circles {len(pick)}", lambda s: fillet(pick, radius=r * s), trait="tangent_chain")


def _axial_hole(b, rng):
    from build123d import Cylinder, Pos

    sx, sy, sz = b.size()
    r = float(min(sx, sy) * rng.uniform(0.05, 0.2))
    bb = b.solid.bounding_box()
    c = bb.center()
    return b.apply("axial hole", lambda s: b.solid - Pos(c.X, c.Y, c.Z) * Cylinder(r * s, 1.5 * sz))


def _swept_base_plate(b, rng):
    """Stand the sweep on a plate, the junction filleted (B-spline meets plane through a blend)."""
    from build123d import Box, Pos, fillet

    sx, sy, _ = b.size()
    bb = b.solid.bounding_box()
    t = float(rng.uniform(3, 8))
    w = float(max(sx, sy) * rng.uniform(0.8, 1.2))
    rf = float(rng.uniform(0.5, 2.0))

    def make(s):
        plate = Pos(0.5 * (bb.min.X + bb.max.X), 0.5 * (bb.min.Y + bb.max.Y), bb.min.Z - 0.5 * t + 1e-3) * Box(w, w, t)
        part = b.solid + plate
        if rng_fillet:
            joint = [e for e in _edges_at(part, bb.min.Z + 1e-3) if e.geom_type.name != "LINE"]
            part = fillet(joint, radius=rf * s) if joint else part
        return part

    rng_fillet = rng.uniform() < 0.6
    return b.apply("plate", make, trait="freeform")


# ----------------------------------------------------------------------------------------------------------------------
# Families and the public entry point

_PRISMATIC = ("holes", "pocket", "boss", "rib", "vertical", "top", "tiny", "fillet_var", "holes", "pocket")


def _feature(b, rng, name):
    if name in ("vertical", "top", "all", "tiny", "all_chamfer"):
        return _blend(b, rng, name)
    return {"holes": _holes, "pocket": _pocket, "boss": _boss, "rib": _rib, "shell": _shell,
            "fillet_var": _variable_fillet, "bolt": _bolt_circle, "circles": _round_circles,
            "axial": _axial_hole, "plate": _swept_base_plate}[name](b, rng)


def _family_prismatic(rng):
    base, desc = _base_prismatic(rng)
    b = _Builder(rng, base, "prismatic")
    b.meta["ops"].append(desc)
    if rng.uniform() < 0.2:
        _feature(b, rng, "shell")
    for _ in range(int(rng.integers(0, 8))):
        _feature(b, rng, _PRISMATIC[int(rng.integers(len(_PRISMATIC)))])
    return b


def _base_pyramid(rng):
    """A pyramid on a regular 4- or 5-gon: its apex is where 4 or 5 edges (then blends) meet."""
    from build123d import Plane, RegularPolygon, Vertex, loft

    n, r = int(rng.integers(4, 6)), float(rng.uniform(15, 40))
    return loft([Plane.XY * RegularPolygon(r, n), Vertex(0, 0, float(r * rng.uniform(0.6, 1.5)))]), f"pyramid {n}"


def _family_blended(rng):
    """Every edge blended: three blends meet at each corner of a block, four or five at a pyramid's apex."""
    pyramid = rng.uniform() < 0.3
    base, desc = _base_pyramid(rng) if pyramid else _base_prismatic(rng)
    b = _Builder(rng, base, "blended")
    b.meta["ops"].append(desc)
    for name in [("pocket", "holes", "boss")[int(rng.integers(3))] for _ in range(int(rng.integers(0, 3)))]:
        if not pyramid:
            _feature(b, rng, name)
    if rng.uniform() < 0.5:  # before the blends: after them every straight edge is tangent to a fillet
        _feature(b, rng, "fillet_var")
    _feature(b, rng, "all" if rng.uniform() < 0.8 else "all_chamfer")
    return b


def _family_with_options(family, base, options, *, freeform=False):
    """A family: ``base(rng)``, then each ``(feature, probability)`` of ``options`` in order, drawn independently."""

    def build(rng):
        shape, desc = base(rng)
        b = _Builder(rng, shape, family)
        b.meta["ops"].append(desc)
        if freeform:
            b.meta["traits"].append("freeform")
        for name, p in options:
            if rng.uniform() < p:
                _feature(b, rng, name)
        return b

    return build


_family_revolved = _family_with_options("revolved", _base_revolved,
                                        [("circles", 0.5), ("bolt", 0.5), ("axial", 0.5), ("tiny", 0.5)])
_family_lofted = _family_with_options("lofted", _base_lofted, [("top", 0.35), ("axial", 0.35), ("holes", 0.35)],
                                      freeform=True)
_family_swept = _family_with_options("swept", _base_swept, [("plate", 0.6)], freeform=True)
_family_primitive = _family_with_options("primitive", _base_primitive, [])


#: family and its weight (share of the seeds): prismatic parts are the commonest machined parts
FAMILIES = (
    ("prismatic", _family_prismatic, 0.40),
    ("blended", _family_blended, 0.15),
    ("revolved", _family_revolved, 0.2),
    ("lofted", _family_lofted, 0.1),
    ("swept", _family_swept, 0.1),
    ("primitive", _family_primitive, 0.05),
)


def _face_types(solid):
    """(recon's type name, OCC's type name) of every face, in ``solid.faces()`` order."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    out = []
    for f in solid.faces():
        occ = BRepAdaptor_Surface(f.wrapped).GetType().name.replace("GeomAbs_", "")
        name = {"Plane": "plane", "Cylinder": "cylinder", "Cone": "cone", "Sphere": "sphere", "Torus": "torus"}
        out.append((name.get(occ, "bspline"), occ))
    return out


def part(seed: int):
    """The corpus part of ``seed``: ``(solid, meta)``, the solid one valid build123d ``Solid``.

    ``meta``: seed, family, ops (features applied, ``@scale`` where retried smaller), dropped (features that
    OpenCascade could not build at any size tried), traits (tangent_chain, corner_blend, variable_fillet,
    small_face, thin_wall, many_holes, freeform), faces, face_types (recon's names: every OCC type other than
    plane/cylinder/cone/sphere/torus counts as bspline), occ_types, face_areas, volume, area, diagonal,
    area_ratio (smallest / largest face).
    """
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: expected a non-negative integer, got {seed!r}")
    rng = np.random.default_rng(int(seed))
    weights = np.array([w for _, _, w in FAMILIES])
    name, build, _ = FAMILIES[int(rng.choice(len(FAMILIES), p=weights / weights.sum()))]
    b = build(rng)
    solid = b.solid
    if not solid.is_valid or len(solid.solids()) != 1:  # every step is checked; this is the last word
        raise RuntimeError(f"seed {seed}: the part is not one valid solid")
    meta = dict(b.meta)
    meta.update(seed=int(seed), **solid_meta(solid))
    if "bspline" in meta["face_types"] and "freeform" not in meta["traits"]:
        meta["traits"].append("freeform")
    return solid, meta


def solid_meta(solid) -> dict:
    """What the corpus records of any true solid: faces, face_types (recon's names), occ_types, face_areas, volume,
    area, diagonal, area_ratio (smallest / largest face)."""
    types = _face_types(solid)
    areas = [float(f.area) for f in solid.faces()]
    bb = solid.bounding_box()
    return dict(
        faces=len(types), face_types=[t for t, _ in types], occ_types=[o for _, o in types],
        face_areas=areas, volume=float(solid.volume), area=float(sum(areas)),
        diagonal=float(math.dist((bb.min.X, bb.min.Y, bb.min.Z), (bb.max.X, bb.max.Y, bb.max.Z))),
        area_ratio=float(min(areas) / max(areas)),
    )
