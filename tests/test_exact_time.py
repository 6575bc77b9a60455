"""The exact path's cheap answers (bench/exact.md "s39-time"): the algebraic proof that no surface of a type holds
the vertices, weighed by each surface's own gradient; the memo of questions already asked; unions implied to fail."""

from functools import partial

import numpy as np

import recon.segment._exact as ex
from recon.mesh import clean_mesh
from recon.segment._exact import roundoff
from recon.segment._exact_freeform import impossible_types
from recon.segment._exact_memo import Failures


def _grid(f, nu: int, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices f(u, v) on an nu × nv grid of [0, 1]² (float32, as an STL keeps them) and its two triangles a cell."""
    u, v = np.meshgrid(np.linspace(0, 1, nu), np.linspace(0, 1, nv), indexing="ij")
    V = np.asarray(f(u.ravel(), v.ravel()), dtype=float).T
    i = np.arange(nu * nv).reshape(nu, nv)
    a, b, c, d = i[:-1, :-1].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel(), i[:-1, 1:].ravel()
    return V.astype(np.float32).astype(float), np.r_[np.c_[a, b, c], np.c_[a, c, d]]


def _torus_band(u, v, R=20.0, r=3.0, du=0.6, dv=0.8):
    a, b = du * u, dv * v
    return (R + r * np.cos(b)) * np.cos(a), (R + r * np.cos(b)) * np.sin(a), r * np.sin(b)


def _cylinder_band(u, v):
    # radius 5 about an axis through (14, 8, 6) along (0.3, 0, 1)/|.|: not the torus's axis, beside its band
    a, h = 1.2 * u, 6.0 * v
    d = np.array([0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0)
    e1 = np.cross(d, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    p = np.array([14.0, 8.0, 6.0])[:, None] + 5.0 * (np.cos(a) * e1[:, None] + np.sin(a) * e2[:, None]) + h * d[:, None]
    return p[0], p[1], p[2]


def _counted(monkeypatch) -> dict:
    calls = {k: 0 for k in ex.FITTERS}
    for kind, fitter in list(ex.FITTERS.items()):
        def wrapped(*a, _k=kind, _f=fitter, **kw):
            calls[_k] += 1
            return _f(*a, **kw)
        monkeypatch.setitem(ex.FITTERS, kind, wrapped)
    return calls


def test_a_torus_band_beside_a_cylinder_off_its_axis_is_no_surface_without_a_fit(monkeypatch):
    """Two bands, one of a torus and one of a cylinder on another axis, each a grid of exact vertices: no sphere,
    quadric or cyclide holds both (a quartic holding a cylinder's patch is the cylinder times a quadric, whose quartic
    part is no multiple of s²), so the proof answers and no fitter runs; the torus's band alone gets its torus."""
    Vt, Ft = _grid(_torus_band, 9, 7)
    Vc, Fc = _grid(_cylinder_band, 7, 7)
    V, F = np.r_[Vt, Vc], np.r_[Ft, Fc + len(Vt)]
    eps, sag = roundoff(V), 0.01 * float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    assert impossible_types(V, eps) == {"sphere", "cylinder", "cone", "torus"}
    calls = _counted(monkeypatch)
    assert ex._candidates(V, F, np.arange(len(V)), np.arange(len(F)), eps, sag) == []
    assert sum(calls.values()) == 0
    fits = ex._candidates(Vt, Ft, np.arange(len(Vt)), np.arange(len(Ft)), roundoff(Vt), sag)
    assert [f.type for f in fits] == ["torus"] and calls["torus"] == 1
    assert abs(fits[0].params["major_radius"] - 20.0) < 1e-3 and abs(fits[0].params["minor_radius"] - 3.0) < 1e-3


def test_a_narrow_torus_band_rules_out_the_quadrics_and_never_its_torus():
    """A fillet's band (R 30, r 1.5; 0.3 rad by 0.5 rad): its vertices lie within round-off of quadrics only to
    first order in the band's width; each quadric weighed by its own gradient at the points misses them by more than
    twice the round-off, so sphere, cylinder and cone are ruled out without a fit (the bound by the largest gradient
    any unit coefficient vector has was 5x looser and ruled out only the sphere). The torus never is, nor any type
    whose surface holds the points (a sphere, a cylinder, a cone)."""
    V, _ = _grid(lambda u, v: _torus_band(u, v, R=30.0, r=1.5, du=0.3, dv=0.5), 12, 12)
    V = V + [5.0, -3.0, 2.0]
    assert impossible_types(V, roundoff(V)) == {"sphere", "cylinder", "cone"}
    rng = np.random.default_rng(0)
    u, v = rng.uniform(0, 2 * np.pi, 200), rng.uniform(0, np.pi, 200)
    z = rng.uniform(1, 10, 200)
    for P, kind in ((7.0 * np.c_[np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], "sphere"),
                    (np.c_[3.0 * np.cos(u), 3.0 * np.sin(u), 10 * z], "cylinder"),
                    (np.c_[0.5 * z * np.cos(u), 0.5 * z * np.sin(u), z], "cone")):
        P = (P + [5.0, -3.0, 2.0]).astype(np.float32).astype(float)
        assert kind not in impossible_types(P, roundoff(P))


def test_a_union_holding_a_failed_union_at_no_looser_round_off_is_implied_to_fail():
    """No surface holds a set that holds a part it failed on; a looser round-off on one of the part's vertices (the
    second pass's rims) asks a new question."""
    failed = Failures()
    failed.add(np.array([2, 5, 9]), np.array([1.0, 1.0, 1.0]))
    assert failed.implied(np.array([1, 2, 5, 9]), np.array([3.0, 1.0, 1.0, 0.5]))
    assert not failed.implied(np.array([1, 2, 5, 9]), np.array([1.0, 1.0, 2.0, 1.0]))
    assert not failed.implied(np.array([2, 5, 7]), np.array([1.0, 1.0, 1.0]))


def test_a_question_asked_again_is_answered_without_a_fit(monkeypatch):
    """The same vertices, triangles, round-off and types: the memo's answer, one fit for both; another round-off
    per vertex is another question."""
    mesh = clean_mesh(*_grid(_torus_band, 6, 5))
    V, F = mesh.vertices, mesh.faces
    at = ex._Atoms.of(mesh, np.arange(len(F)))
    calls = []
    real = ex._candidates
    monkeypatch.setattr(ex, "_candidates", lambda *a, **k: calls.append(1) or real(*a, **k))
    ids, tris = np.arange(len(V)), np.arange(len(F))
    eps, sag = roundoff(V), 0.01 * float(mesh.diagonal)
    first = ex._asked(at, ids, tris, eps, sag)
    assert ex._asked(at, ids, tris[::-1], eps, sag) is first and len(calls) == 1
    ex._asked(at, ids, tris, np.full(len(V), eps) * (1 + (ids == 3)), sag)
    assert len(calls) == 2
