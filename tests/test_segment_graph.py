"""The generic §3 segment-graph functions on small hand-made complexes with known answers."""

import numpy as np
import pytest
from scipy.spatial import Delaunay

from recon import segment_graph as sg


def grid_cells(n):
    """An n×n grid of unit squares, two counter-clockwise triangles each; square (i, j) owns cells 2k, 2k+1."""
    vid = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)  # vid[x, y]
    pts = np.array([[x, y] for x in range(n + 1) for y in range(n + 1)], dtype=float)
    cells, square = [], []
    for i in range(n):
        for j in range(n):
            a, b, c, d = vid[i, j], vid[i + 1, j], vid[i + 1, j + 1], vid[i, j + 1]
            cells += [[a, b, c], [a, c, d]]
            square += [(i, j), (i, j)]
    return pts, np.array(cells), square


def test_degree_and_bridges_on_a_tree():
    # path 0-1-2-3-4 with a branch 2-5: degrees 1,2,3,2,1,1; every edge touches a degree != 2 ...
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [2, 5]])
    deg = sg.vertex_degree(edges, 6)
    assert deg.tolist() == [1, 2, 3, 2, 1, 1]
    assert sg.bridge_mask(edges, deg).tolist() == [True, True, True, True, True]
    # ... while a longer path 0-1-2-3 has its middle edge between two degree-2 vertices: not a bridge
    edges = np.array([[0, 1], [1, 2], [2, 3]])
    assert sg.bridge_mask(edges, sg.vertex_degree(edges, 4)).tolist() == [True, False, True]


def test_cell_neighbors_matches_qhull():
    rng = np.random.default_rng(1)
    tri = Delaunay(rng.random((200, 2)))
    ours = sg.cell_neighbors(tri.simplices)
    assert np.array_equal(ours, tri.neighbors)


def test_cut_components_on_a_strip():
    pts, cells, square = grid_cells(3)
    nb = sg.cell_neighbors(cells)
    pairs, _ = sg.cell_adjacency(nb)
    # 9 squares × 3 inner adjacencies... : 9 diagonals + 12 grid edges between squares
    assert len(pairs) == 9 + 12
    # cut every adjacency between squares of different column: 3 columns of 6 cells
    col = np.array([s[0] for s in square])
    cut = col[pairs[:, 0]] != col[pairs[:, 1]]
    n, label = sg.cut_components(len(cells), pairs, cut)
    assert n == 3
    assert np.array_equal(label, col)  # numbered by lowest cell, which is column order
    # inactive cells get -1 and do not count
    active = col != 1
    pairs_a, _ = sg.cell_adjacency(nb, active=active)
    n, label = sg.cut_components(len(cells), pairs_a, np.zeros(len(pairs_a), bool), active=active)
    assert n == 2 and np.all(label[col == 1] == -1)


def test_part_kinds_precedence():
    # part 0: degrees 3 and 2 -> junction; part 1: 1 and 2 -> terminal; part 2: 2, 2 -> linear;
    # part 3: a lone degree-0 vertex -> junction; part 4: nothing -> NO_SKELETON
    vpart = np.array([0, 0, 1, 1, 2, 2, 3])
    deg = np.array([3, 2, 1, 2, 2, 2, 0])
    kinds = sg.part_kinds(vpart, deg, 5)
    assert kinds.tolist() == [sg.JUNCTION, sg.TERMINAL, sg.LINEAR, sg.JUNCTION, sg.NO_SKELETON]


def loop_areas(pts, loop_v, offsets):
    out = []
    for s, e in zip(offsets[:-1], offsets[1:]):
        r = pts[loop_v[s:e]]
        out.append(0.5 * float(np.dot(r[:, 0], np.roll(r[:, 1], -1)) - np.dot(r[:, 1], np.roll(r[:, 0], -1))))
    return out


def test_boundary_loops_outer_and_hole():
    pts, cells, square = grid_cells(3)
    label = np.array([-1 if s == (1, 1) else 0 for s in square])  # ring of 8 squares around a hole
    nb = sg.cell_neighbors(cells)
    loop_v, offsets, loop_part = sg.part_boundary_loops(cells, nb, label)
    assert loop_part.tolist() == [0, 0]
    assert sorted(loop_areas(pts, loop_v, offsets)) == [-1.0, 9.0]  # CCW outer of area 9, CW hole of area 1
    assert sorted(np.diff(offsets).tolist()) == [4, 12]


@pytest.mark.parametrize("with_points", [True, False])
def test_boundary_loops_split_at_a_pinch(with_points):
    # 4×4 grid; the part surrounds square (2,1), which touches the outside at grid point (2,2):
    # the border must come out as one simple outer loop (area 8) and one hole (area 1), not one figure-eight
    pts, cells, square = grid_cells(4)
    region = {(1, 1), (2, 2), (3, 2), (3, 1), (3, 0), (2, 0), (1, 0)}
    label = np.array([0 if s in region else -1 for s in square])
    nb = sg.cell_neighbors(cells)
    loop_v, offsets, loop_part = sg.part_boundary_loops(cells, nb, label, points=pts if with_points else None)
    areas = sorted(loop_areas(pts, loop_v, offsets))
    assert areas == [-1.0, 8.0]
    assert sum(areas) == pytest.approx(len(region))
    # each loop visits each vertex once
    for s, e in zip(offsets[:-1], offsets[1:]):
        assert len(set(loop_v[s:e].tolist())) == e - s


def test_boundary_loops_of_several_parts():
    # two columns of a 2×2 grid as two parts: two unit-width rectangles of area 2, sharing one separator
    pts, cells, square = grid_cells(2)
    label = np.array([s[0] for s in square])
    loop_v, offsets, loop_part = sg.part_boundary_loops(cells, sg.cell_neighbors(cells), label)
    assert loop_part.tolist() == [0, 1]
    assert loop_areas(pts, loop_v, offsets) == [2.0, 2.0]
