"""Seeds of the region growing (recon.decompose._growing): the neighbourhood a seed grown too small retires."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.csgraph import connected_components
import scipy.sparse as sp

from recon.decompose import _growing, _regions, decompose
from recon.decompose._regionfit import _Ctx
from recon.decompose._topology import topology
from recon.features import NOISE_FACTOR
from recon.fixtures import load_fixture


def _sheets(n: int, gap: float):
    """Two parallel unit-spaced grids of n × n squares (2 triangles each), ``gap`` apart, not connected."""
    x, y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0), indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i.ravel(), i.ravel() + (n + 1), i.ravel() + (n + 2), i.ravel() + 1
    f = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    V = np.vstack([v, v + [0.0, 0.0, gap]])
    F = np.vstack([f, f + len(v)])
    topo = topology(F, len(V))
    adj = np.where(topo.twin >= 0, topo.twin // 3, -1).reshape(-1, 3)
    cr = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    area = 0.5 * np.linalg.norm(cr, axis=1)
    fn = cr / (2 * area[:, None])
    ctx = _Ctx(V, F, adj, np.zeros((0, 3), np.int64), topo.edges, fn, np.zeros_like(V), 0.1, 0.5, 1.0, area=area,
               crease=-2.0)
    return ctx, len(f)


@pytest.mark.parametrize("radius", [0.7, 2.0, 3.5])
def test_near_is_the_window_along_the_surface(radius):
    # differential: the free triangles within `radius` of the region (centroid to nearest region centroid), in the
    # region's own connected piece of them; nothing of the other sheet, though it lies within `radius` (a thin wall)
    ctx, per_sheet = _sheets(12, 0.5 * radius)
    rng = np.random.default_rng(1)
    free = rng.random(len(ctx.F)) > 0.2
    region = np.array([t for t in (140, 141, 142, 165) if free[t]])
    free[region] = True
    region = np.unique(np.r_[region, 140])
    free[140] = True
    got = np.sort(_growing._near(ctx, region, free, radius))
    c = ctx.centroid
    d = np.min(np.linalg.norm(c[:, None, :] - c[region][None, :, :], axis=2), axis=1)
    ok = free & (d <= radius)
    ok[region] = True
    src = np.repeat(np.arange(len(ctx.F)), 3)
    nb = ctx.adj.ravel()
    keep = (nb >= 0) & ok[src] & ok[np.maximum(nb, 0)]
    g = sp.coo_matrix((np.ones(int(keep.sum())), (src[keep], nb[keep])), shape=(len(ctx.F),) * 2)
    _, comp = connected_components(g, directed=False)
    want = np.flatnonzero(ok & np.isin(comp, comp[region]))
    assert np.array_equal(got, want)
    assert (got < per_sheet).all()


def _retire_of(part: str, variant: str, monkeypatch) -> tuple[float, float]:
    """The retire distance the decomposition of a fixture ran with, and its noise estimate."""
    seen = []
    seeded = _regions._seed_regions

    def record(ctx, *args, **kwargs):
        seen.append(ctx.retire)
        return seeded(ctx, *args, **kwargs)

    monkeypatch.setattr(_regions, "_seed_regions", record)
    fx = load_fixture(part, variant)
    dec = decompose((fx.vertices, fx.faces), jobs=1)
    assert seen and len(set(seen)) == 1
    return seen[0], dec.noise


def test_retire_is_the_noise_window_and_off_on_clean_meshes(monkeypatch):
    # noise-free: the tolerance is at its floor, only a region's own triangles are retired (main's behaviour)
    retire, _ = _retire_of("plate_holes", "clean", monkeypatch)
    assert retire == 0.0
    # noisy (σ = 0.2 % of the diagonal): the feature window's noise term, NOISE_FACTOR σ̂
    retire, noise = _retire_of("plate_holes", "noisy20", monkeypatch)
    assert noise > 0 and retire == NOISE_FACTOR * noise
