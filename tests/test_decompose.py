"""Surface decomposition: the rounded box's 6/12/8, ground-truth IoU, invariances, CLI."""

import json

import numpy as np
import pytest
import trimesh

from recon.cli import main
from recon.decompose import decompose, face_recovery
from recon.decompose._regions import TOL_FLOOR
from bench.synthetic import rounded_box
from recon.fixtures import load_fixture


def _areas(V, F):
    return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)


EXPECTED = {"patch": 6, "junction": 8, "linear": 12, "terminal": 0}


@pytest.fixture(scope="module")
def box():
    V, F, L = rounded_box(spacing=0.5)
    return V, F, L, decompose((V, F))


def test_face_recovery_hand_made():
    # two true faces of area 1+1 and 2; parts split the first face's triangles 1 : 1 with the second
    true = np.array([0, 0, 1])
    parts = np.array([5, 7, 7])
    r = face_recovery(parts, true, np.array([1.0, 1.0, 2.0]))
    assert r.best_part.tolist() == [5, 7]  # tie broken by lowest part id
    assert r.iou == pytest.approx([0.5, 2.0 / 3.0])
    assert r.recovered == 1.0


def test_rounded_box_counts_and_recovery(box):
    V, F, L, d = box
    assert d.counts() == EXPECTED
    r = face_recovery(d.labels, L, _areas(V, F))
    assert r.recovered >= 0.95
    # every patch touches 4 linear parts, every junction 3, every linear 2 patches + 2 junctions
    kinds = [p.kind for p in d.parts]
    for p in d.parts:
        nk = sorted(kinds[j] for j in p.neighbours)
        if p.kind == "patch":
            assert nk.count("linear") == 4
        elif p.kind == "junction":
            assert nk == ["linear"] * 3  # a sphere octant meets the planes only at their corners
        else:
            assert nk.count("patch") == 2 and nk.count("junction") == 2
    assert not any(p.sharp for p in d.parts)  # 3 mm fillets at a 0.8 mm scale are blends
    assert np.bincount(d.labels).sum() == len(F)


def test_sharp_box_is_six_planes():
    # a clean box with sharp edges: six planes sharing edges, nothing critical (a sharp edge is a shared border)
    V, F, L = rounded_box(size=(20, 16, 12), radius=0.0, spacing=0.5)
    d = decompose((V, F))
    assert d.counts() == {"patch": 6, "junction": 0, "linear": 0, "terminal": 0}
    assert not d.critical.any()
    cr = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n = cr / np.linalg.norm(cr, axis=1, keepdims=True)
    for p in range(6):  # every patch is one side: all its triangle normals equal
        assert np.abs(n[d.labels == p] - n[d.labels == p][0]).max() < 1e-9


# -- ground-truth fixtures (recon.fixtures; fixtures/data is in the repository) -------------------------------


def _fixture(part, variant):
    return load_fixture(part, variant)


def test_fixture_box_fillet_counts():
    fx = _fixture("box_fillet", "clean")
    d = decompose((fx.vertices, fx.faces))
    assert d.counts() == EXPECTED  # 6 planes, 12 fillets, 8 corner spheres
    r = face_recovery(d.labels, fx.labels, _areas(fx.vertices, fx.faces))
    assert r.recovered == 1.0 and r.mean_iou > 0.95


# targets of the issue: >= 95 % of the true faces recovered on clean meshes, >= 85 % at sigma = 0.2 % of the
# diagonal. Only the fixtures that meet them are here; bench/decompose.md has the numbers for the others.
@pytest.mark.parametrize(
    "part, variant, target",
    [
        ("box_fillet", "noisy20", 0.85),
        ("prism", "clean", 0.95),
        ("prism", "noisy20", 0.85),
        ("plate_holes", "clean", 0.95),
        ("plate_holes", "noisy20", 0.85),
        ("prism", "coarse", 0.95),  # a CAD tessellation: the same faces at any resolution
    ],
)
def test_fixture_face_recovery(part, variant, target):
    fx = _fixture(part, variant)
    d = decompose((fx.vertices, fx.faces))
    r = face_recovery(d.labels, fx.labels, _areas(fx.vertices, fx.faces))
    assert r.recovered >= target


@pytest.mark.parametrize("variant, mean_iou", [("clean", 1.0), ("noisy05", 1.0), ("open", 1.0), ("noisy20", 0.99)])
def test_lofted_side_is_one_free_form_patch(variant, mean_iou):
    """Issue #4: the lofted side is curved everywhere at the smoothing window's scale (0.6 % of it smooth on
    the clean mesh), so the seeds tile it with some forty small cylinders that all count as blends. It meets
    the two planes at sharp edges, as no fillet network does: it is one patch, and the parts are the true faces
    (the very triangles of each; at σ = 0.2 % of the diagonal a few triangles on the wrong side of an edge,
    measured 4 of the top plane's 898, mean IoU 0.9986)."""
    fx = _fixture("lofted", variant)
    d = decompose((fx.vertices, fx.faces))
    assert d.counts() == {"patch": 3, "junction": 0, "linear": 0, "terminal": 0}
    r = face_recovery(d.labels, fx.labels, _areas(fx.vertices, fx.faces))
    assert r.recovered == 1.0 and r.mean_iou >= mean_iou


def _same_partition(a, b):
    """Labels equal up to renumbering: the pairing of labels is a bijection."""
    pairs = np.unique(np.stack([a, b], axis=1), axis=0)
    return len(pairs) == len(np.unique(a)) == len(np.unique(b))


def test_rigid_motion_scaling_and_permutation(box):
    V, F, L, d = box
    q, _ = np.linalg.qr(np.random.default_rng(3).normal(size=(3, 3)))
    d2 = decompose((3.0 * V @ q.T + [10, 20, -5], F))
    assert d2.counts() == d.counts()
    agree = face_recovery(d2.labels, d.labels, _areas(V, F))
    assert agree.mean_iou > 0.98
    perm = np.random.default_rng(4).permutation(len(F))
    d3 = decompose((V, F[perm]))
    assert d3.counts() == d.counts()
    assert _same_partition(d3.labels, d.labels[perm])


def test_retessellation_same_counts():
    V, F, L = rounded_box(spacing=1.0)
    assert decompose((V, F)).counts() == EXPECTED


def test_cli(tmp_path):
    V, F, L = rounded_box(radius=3.0, spacing=1.0)
    src = tmp_path / "box.stl"
    trimesh.Trimesh(V, F, process=False).export(src)
    out, png = tmp_path / "d.json", tmp_path / "d.png"
    assert main(["decompose", str(src), "--json", str(out), "--preview", str(png)]) == 0
    doc = json.loads(out.read_text())
    assert len(doc["triangle_labels"]) == len(F)
    kinds = [p["kind"] for p in doc["parts"]]
    assert {k: kinds.count(k) for k in EXPECTED} == EXPECTED
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    bad = tmp_path / "bad.stl"
    bad.write_text("not a mesh")
    assert main(["decompose", str(bad), "--json", str(out)]) == 2


def test_tolerance_and_fits_exposed(box):
    # the clean rounded box: every part lies on one analytic surface of the right type and radius
    V, F, L, d = box
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    assert d.tolerance == pytest.approx(TOL_FLOOR * diag)  # noise-free: the floor of max(4 sigma, floor)
    fits = d.extra["fits"]
    assert sorted(fits) == list(range(len(d.parts)))
    want = {"patch": "plane", "linear": "cylinder", "junction": "sphere"}
    for p in d.parts:
        assert fits[p.id].type == want[p.kind]
        if p.kind != "patch":
            assert fits[p.id].params["radius"] == pytest.approx(3.0, abs=1e-6)
        faces = np.flatnonzero(d.labels == p.id)
        # the surfaces are exact: within the old floor 1e-4 diag, far inside the tolerance
        assert np.abs(fits[p.id].distance(V[np.unique(F[faces])])).max() <= 2e-4 * diag


@pytest.mark.parametrize("kind", ["sphere", "cylinder", "cone", "torus"])
def test_closed_form_fits_recover_exact_surfaces(kind):
    # points on a known surface patch (exact normals): the closed form alone is within 1e-6 of it
    from importlib import import_module

    qf = import_module("recon.fit")
    rng = np.random.default_rng(7)
    u, v = rng.uniform(0.2, 1.4, 200), rng.uniform(-0.6, 0.6, 200)
    if kind == "sphere":
        p = 5.0 * np.c_[np.cos(u) * np.cos(v), np.sin(u) * np.cos(v), np.sin(v)] + [1, 2, 3]
        n = p - [1, 2, 3]
    elif kind == "cylinder":
        p = np.c_[4.0 * np.cos(u), 4.0 * np.sin(u), 3 * v]
        n = np.c_[np.cos(u), np.sin(u), 0 * v]
    elif kind == "cone":  # half-angle 0.5 rad, apex at the origin
        h = 3.0 + 2 * v
        p = np.c_[h * np.tan(0.5) * np.cos(u), h * np.tan(0.5) * np.sin(u), h]
        n = np.c_[np.cos(0.5) * np.cos(u), np.cos(0.5) * np.sin(u), -np.sin(0.5) * np.ones_like(u)]
    else:  # R = 6, r = 2
        p = np.c_[(6 + 2 * np.cos(2 * v)) * np.cos(u), (6 + 2 * np.cos(2 * v)) * np.sin(u), 2 * np.sin(2 * v)]
        n = np.c_[np.cos(2 * v) * np.cos(u), np.cos(2 * v) * np.sin(u), np.sin(2 * v)]
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    fit = qf.quick_fit(kind, p, n, 1e-6, refine=False)
    assert fit is not None and fit.type == kind
    assert fit.deviation["max"] < 1e-6
    # the analytic normals agree with the true ones (up to sign)
    assert np.abs(np.einsum("ij,ij->i", qf.surface_normals(fit, p), n)).min() > 1 - 1e-9
    # a plane is not mistaken for a curved surface: the closed forms refuse it as degenerate
    flat = np.c_[u, v, np.zeros_like(u)]
    assert qf.quick_fit(kind, flat, np.tile([0.0, 0.0, 1.0], (200, 1)), 1e-3, refine=False) is None


def test_split_by_fitting_finds_the_four_fillets_of_a_pocket_ring():
    """pocket's floor fillets (radius 3) meet at the pocket's sharp corners: the decomposition sees one ring,
    one linear part, that no surface fits. Grown from seeds inside the ring, the regions are its four true
    cylinders, triangle for triangle, with the true radius and axes along x and y (the mesh vertices lie on
    the true surfaces, so the fit is exact to round-off: 1e-6 of a 3 mm radius is generous)."""
    from recon.decompose import split_by_fitting
    from recon.fixtures import load_fixture
    from recon.segment import vertex_normals

    fx = load_fixture("pocket", "clean")
    V, F = fx.vertices, fx.faces
    cylinders = [f.index for f in fx.true_faces if f.type == "cylinder"]
    ring = np.flatnonzero(np.isin(fx.labels, cylinders))
    cr = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    area = 0.5 * np.linalg.norm(cr, axis=1)
    vn = vertex_normals(V, F, cr / (2 * area[:, None]), area)
    found = split_by_fitting(V, F, ring, vnormal=vn, tolerance=TOL_FLOOR * float(np.linalg.norm(np.ptp(V, axis=0))), min_area=0.05 * area[ring].sum())
    assert len(found) == 4
    got = sorted(sorted(np.unique(fx.labels[r]).tolist()) for r, _ in found)
    assert got == sorted([c] for c in cylinders)
    for r, fit in found:
        assert len(r) == int((fx.labels == fx.labels[r[0]]).sum())
        assert fit.type == "cylinder" and fit.params["radius"] == pytest.approx(3.0, rel=1e-6)
        axis = np.abs(np.asarray(fit.params["axis_dir"]))
        assert axis.max() == pytest.approx(1.0, abs=1e-6) and np.argmax(axis) in (0, 1)


@pytest.mark.parametrize("span, expected", [(2 * np.pi, 2 * np.pi), (np.pi / 2, np.pi / 2)])
def test_turn_of_a_cylinder_region(span, expected):
    """A fillet's cylinder covers a quarter turn, a hole or a boss a full one (then it is no blend): points at
    60 angles over ``span`` on an r = 5 cylinder about a tilted axis cover ``span`` less one step
    (a full turn has no gap but the step itself)."""
    from types import SimpleNamespace

    from recon.decompose._blends import _turn
    from recon.fit import SurfaceFit

    d = np.array([1.0, 2.0, 2.0]) / 3.0
    u = np.cross(d, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(d, u)
    n = 60
    full = span >= 2 * np.pi - 1e-12
    t = np.linspace(0.0, span, n, endpoint=not full)
    h = np.linspace(-3.0, 3.0, n)
    pts = np.array([1.0, 1.0, 1.0]) + 5.0 * (np.outer(np.cos(t), u) + np.outer(np.sin(t), w)) + np.outer(h, d)
    fit = SurfaceFit("cylinder", {"axis_point": [1.0, 1.0, 1.0], "axis_dir": d.tolist(), "radius": 5.0}, {}, n)
    step = span / n if full else 0.0
    got = _turn(SimpleNamespace(centroid=pts), fit, np.arange(n))
    assert got == pytest.approx(expected - step, abs=1e-9)


def test_an_unreferenced_vertex_changes_no_part():
    """The separators key mesh edges by the vertex count, and the cut must use the same keys: with one unreferenced
    vertex after the last one, box_fillet's critical region was not cut at all (7 parts instead of 26)."""
    import dataclasses

    from recon.fixtures import load_fixture
    from recon.mesh import clean_mesh

    fx = load_fixture("box_fillet", "clean")
    mesh = clean_mesh(fx.vertices, fx.faces)
    extra = dataclasses.replace(mesh, vertices=np.vstack([mesh.vertices, mesh.vertices.max(axis=0) + 100.0]))
    a, b = decompose(mesh), decompose(extra)
    assert len(a.parts) == 26
    assert np.array_equal(a.labels, b.labels)
    assert [(p.kind, p.sharp) for p in a.parts] == [(p.kind, p.sharp) for p in b.parts]


@pytest.mark.parametrize("part, variant", [("plate_holes", "noisy20"), ("lofted", "noisy05")])
def test_two_processes_give_the_same_decomposition(part, variant, monkeypatch):
    """jobs=2 grows the next seed in a forked worker while this one grows, and keeps the worker's region only
    when it is what growing one after the other gives. On these fixtures both cases happen (a guess that held,
    one that did not), and every region grown from seeds is the same, triangle for triangle and parameter for
    parameter, and so is the decomposition. (The regions are compared because the later steps can hide a
    difference: keeping every guess changes the seeded regions of both fixtures, not their final labels.)"""
    from recon.decompose import _growing, _regions

    if not _regions._Worker.available():
        pytest.skip("no fork here")
    fx = _fixture(part, variant)
    monkeypatch.setattr(_regions, "PARALLEL_MIN_TRIANGLES", 0)  # the fixtures are below the size it pays from
    verdicts, grown = [], []
    holds, seeded = _growing._speculation_holds, _regions._seed_regions
    monkeypatch.setattr(_growing, "_speculation_holds", lambda *a: verdicts.append(holds(*a)) or verdicts[-1])

    def record(*args, **kwargs):
        out = seeded(*args, **kwargs)
        grown.append([(faces.tolist(), fit.type, fit.params) for faces, fit in out])
        return out

    monkeypatch.setattr(_regions, "_seed_regions", record)
    one = decompose((fx.vertices, fx.faces), jobs=1)
    assert verdicts == []
    seeded_one, grown[:] = list(grown), []
    two = decompose((fx.vertices, fx.faces), jobs=2)
    assert True in verdicts and False in verdicts
    assert grown == seeded_one
    assert np.array_equal(one.labels, two.labels)
    assert [(p.kind, p.sharp, tuple(p.neighbours)) for p in one.parts] == [
        (p.kind, p.sharp, tuple(p.neighbours)) for p in two.parts
    ]
    assert np.array_equal(one.skeleton.vertices, two.skeleton.vertices)
    assert np.array_equal(one.skeleton.edges, two.skeleton.edges)


def _dies(ctx, *args):
    import os

    os._exit(3)


def _hangs(ctx, *args):
    import time

    time.sleep(60)


def _fails(ctx, *args):
    raise MemoryError("no room")


@pytest.mark.parametrize("job", [_dies, _hangs, _fails], ids=["dies", "hangs", "fails"])
def test_a_worker_that_dies_hangs_or_fails_changes_nothing(job, monkeypatch, caplog):
    """The second process can never stall the decomposition nor change it: when it ends, gives no answer within
    the timeout or fails a job, the parent does that work itself and goes on in one process."""
    import time

    from recon.decompose import _regions, _worker

    if not _regions._Worker.available():
        pytest.skip("no fork here")
    fx = _fixture("plate_holes", "noisy20")
    monkeypatch.setattr(_regions, "PARALLEL_MIN_TRIANGLES", 0)
    one = decompose((fx.vertices, fx.faces), jobs=1)
    monkeypatch.setattr(_worker, "WORKER_TIMEOUT", 0.5)
    # the worker is forked after this: it runs the broken job for every job the parent sends
    monkeypatch.setitem(_worker._JOBS, "grow", job)
    monkeypatch.setitem(_worker._JOBS, "fits", job)
    t = time.perf_counter()
    two = decompose((fx.vertices, fx.faces), jobs=2)
    assert time.perf_counter() - t < 30  # not the 60 s the hanging job sleeps
    assert "second process stopped" in caplog.text
    assert np.array_equal(one.labels, two.labels)
    assert [(p.kind, p.sharp, tuple(p.neighbours)) for p in one.parts] == [
        (p.kind, p.sharp, tuple(p.neighbours)) for p in two.parts
    ]
