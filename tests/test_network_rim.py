"""A hole's rim traced from ragged labels (issue 23): the closed edge between a through hole's wall and the flat face
round it winds once round the hole's axis however ragged the labels along the rim are, as long as each label is one
connected piece (what :func:`recon.segment.tidy` leaves)."""

from __future__ import annotations

import numpy as np
import pytest

from recon.network import curve_network

R = 1.0  # the hole's radius
N_THETA = 48  # quads round the axis
N_WALL = 12  # rows of quads down the wall (depth 1.5 R)
N_FLAT = 8  # rows of quads across the flat annulus (out to 3 R)


def _grid(rows: np.ndarray, n_theta: int) -> tuple[np.ndarray, np.ndarray]:
    """Quads (as two triangles each) between consecutive rings of vertex ids ``rows`` (r, n_theta); returns the
    triangles and the (row, column) of the quad each belongs to."""
    tris, quad = [], []
    for k in range(len(rows) - 1):
        for j in range(n_theta):
            a, b = rows[k, j], rows[k, (j + 1) % n_theta]
            c, d = rows[k + 1, (j + 1) % n_theta], rows[k + 1, j]
            tris += [(a, b, c), (a, c, d)]
            quad += [(k, j), (k, j)]
    return np.asarray(tris, dtype=np.int64), np.asarray(quad, dtype=np.int64)


def plate_with_hole() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """An open mesh: the flat annulus ``R ≤ r ≤ 3R`` at z = 0 and the hole's wall ``r = R`` down to z = −1.5 R, sharing
    the rim ring. Returns vertices, triangles (oriented: +z on the flat, towards the axis on the wall), and for every
    triangle its quad's (row, column) and whether it is on the wall."""
    theta = 2 * np.pi * np.arange(N_THETA) / N_THETA
    ring = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    flat_r = np.linspace(R, 3 * R, N_FLAT + 1)
    wall_z = np.linspace(0.0, -1.5 * R, N_WALL + 1)
    flat = np.concatenate([np.c_[r * ring, np.zeros(N_THETA)] for r in flat_r])
    wall = np.concatenate([np.c_[R * ring, np.full(N_THETA, z)] for z in wall_z[1:]])
    vertices = np.concatenate([flat, wall])
    flat_rows = np.arange(len(flat)).reshape(N_FLAT + 1, N_THETA)
    wall_rows = np.concatenate([flat_rows[:1], len(flat) + np.arange(len(wall)).reshape(N_WALL, N_THETA)])
    ft, fq = _grid(flat_rows, N_THETA)  # rim outwards, counter-clockwise about +z: normals +z
    wt, wq = _grid(wall_rows, N_THETA)
    wt = wt[:, ::-1]  # rim downwards: reversed to face the axis, the same side as the flat's +z at the rim
    return (vertices, np.concatenate([ft, wt]), np.concatenate([fq, wq]),
            np.r_[np.zeros(len(ft), bool), np.ones(len(wt), bool)])


def ragged_labels(quad: np.ndarray, on_wall: np.ndarray, rng: np.random.Generator, depth: int) -> np.ndarray:
    """Flat = 0, wall = 1, with the rim ragged column by column: in each column the flat's label reaches up to
    ``depth`` rows down the wall, or the wall's up to ``depth`` rows out across the flat (never both), so each label
    stays one connected piece and the boundary between them is one ragged loop."""
    reach = rng.integers(-depth, depth + 1, size=N_THETA)  # > 0: the flat's label down the wall; < 0: the wall's out
    row, col = quad[:, 0], quad[:, 1]
    labels = on_wall.astype(np.int64)
    labels[on_wall & (row < reach[col])] = 0
    labels[~on_wall & (row < -reach[col])] = 1
    return labels


def _winding(points: np.ndarray) -> float:
    """Turns of the closed polyline ``points`` round the z axis."""
    ang = np.unwrap(np.arctan2(points[:, 1], points[:, 0]))
    return float((ang[-1] - ang[0]) / (2 * np.pi))


def test_plate_with_hole_is_oriented():
    v, f, _, _ = plate_with_hole()
    he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    # every interior edge is used once in each direction: one consistent orientation across the rim
    keys, count = np.unique(he, axis=0, return_counts=True)
    assert count.max() == 1
    both = {tuple(k) for k in keys.tolist()}
    interior = sum((b, a) in both for a, b in keys.tolist())
    assert interior == len(keys) - 2 * N_THETA  # all but the outer circle and the wall's lower end


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("depth", [1, 3])
def test_ragged_rim_winds_once(seed, depth):
    v, f, quad, on_wall = plate_with_hole()
    labels = ragged_labels(quad, on_wall, np.random.default_rng(seed), depth)
    net = curve_network(v, f, labels)
    rim = [e for e in range(net.n_edges) if sorted(net.edge_parts[e].tolist()) == [0, 1]]
    # one closed edge between the flat and the wall, once round the axis: a loop that folds back has winding 0
    assert len(rim) == 1
    e = rim[0]
    assert net.edge_vertices[e, 0] == net.edge_vertices[e, 1]
    assert abs(_winding(net.polyline(e))) == pytest.approx(1.0, abs=1e-9)
    # the loop stays within the ragged band: no farther from the rim ring than `depth` rows of quads
    pts = net.polyline(e)
    assert len(pts) > N_THETA + 1  # ragged: the loop steps up and down the columns, not the rim ring itself
    off_rim = np.maximum(np.linalg.norm(pts[:, :2], axis=1) - R, 0.0) + np.abs(pts[:, 2])
    assert off_rim.max() <= depth * max(2 * R / N_FLAT, 1.5 * R / N_WALL) + 1e-12
