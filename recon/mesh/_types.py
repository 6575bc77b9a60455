"""The cleaned triangle mesh every later stage consumes, and the report of what cleaning fixed.

Bulk data are numpy arrays; derived data (normals, adjacency, ...) are computed once, on first use,
and cached on the instance (a frozen, non-slots dataclass lets ``functools.cached_property`` write
to ``__dict__``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from .._array import row_norms

if TYPE_CHECKING:
    import trimesh

__all__ = ["Mesh", "CleanReport", "VertexFaces"]


@dataclass(frozen=True)
class CleanReport:
    """What :func:`recon.clean_mesh` found and fixed.

    Attributes
    ----------
    n_input_vertices, n_input_faces : int
        Sizes as read (an unwelded STL has three vertices per triangle).
    welded_vertices : int
        Input vertices merged into another one (``n_input_vertices`` minus the distinct welded positions).
    degenerate_faces : int
        Triangles dropped because two corners coincide after welding, or the triangle is flat within the
        weld tolerance (its height over the longest edge is at most ``weld_tolerance``).
    duplicate_faces : int
        Triangles dropped because an earlier triangle has the same three vertices in the same orientation
        (or an opposite copy that could not cancel, see ``double_wall_faces``).
    double_wall_faces : int
        Triangles dropped in pairs: the same three vertices in opposite orientations make a wall of zero
        thickness, and both copies go unless that would open a hole.
    flipped_faces : int
        Kept triangles whose vertex order was reversed to orient their component consistently
        (outward where the component is closed).
    components : int
        Edge-connected bodies.
    boundary_edges : int
        Edges used by exactly one triangle (holes of an open mesh).
    non_manifold_edges : int
        Edges used by three or more triangles.
    inconsistent_edges : int
        Two-triangle edges still traversed in the same direction by both after orientation: non-zero
        only for non-orientable surfaces (a Möbius strip).
    input_boundary_edges, input_non_manifold_edges : int
        The same counts on the triangles as read (after welding, before dropping anything).
    weld_tolerance : float
        Distance used for welding, in mesh units.
    """

    n_input_vertices: int
    n_input_faces: int
    welded_vertices: int
    degenerate_faces: int
    duplicate_faces: int
    double_wall_faces: int
    flipped_faces: int
    components: int
    boundary_edges: int
    non_manifold_edges: int
    inconsistent_edges: int
    input_boundary_edges: int
    input_non_manifold_edges: int
    weld_tolerance: float

    @property
    def closed(self) -> bool:
        """True if every edge is shared by exactly two triangles (a watertight 2-manifold)."""
        return self.boundary_edges == 0 and self.non_manifold_edges == 0

    def summary(self) -> str:
        """One paragraph of plain text for a user."""
        kept = self.n_input_faces - self.degenerate_faces - self.duplicate_faces - self.double_wall_faces
        parts = [
            f"Read {self.n_input_faces:,} triangles on {self.n_input_vertices:,} vertices; "
            f"kept {kept:,} triangles in {self.components:,} component{'s' if self.components != 1 else ''}."
        ]
        fixes = []
        if self.welded_vertices:
            fixes.append(f"welded {self.welded_vertices:,} vertices (tolerance {self.weld_tolerance:.3g})")
        if self.degenerate_faces:
            fixes.append(f"dropped {self.degenerate_faces:,} degenerate triangles")
        if self.duplicate_faces:
            fixes.append(f"dropped {self.duplicate_faces:,} duplicate triangles")
        if self.double_wall_faces:
            fixes.append(f"dropped {self.double_wall_faces:,} triangles of zero-thickness double walls")
        if self.input_non_manifold_edges > self.non_manifold_edges:
            fixes.append(
                f"non-manifold edges went from {self.input_non_manifold_edges:,} to {self.non_manifold_edges:,}"
            )
        if self.flipped_faces:
            fixes.append(f"flipped {self.flipped_faces:,} triangles to orient them consistently")
        parts.append(("Fixed: " + "; ".join(fixes) + ".") if fixes else "Nothing needed fixing.")
        if self.closed:
            parts.append("The mesh is closed and manifold.")
        else:
            issues = []
            if self.boundary_edges:
                issues.append(f"{self.boundary_edges:,} boundary edges (the mesh is open)")
            if self.non_manifold_edges:
                issues.append(f"{self.non_manifold_edges:,} non-manifold edges")
            parts.append("Left as is: " + "; ".join(issues) + ".")
        if self.inconsistent_edges:
            parts.append(f"{self.inconsistent_edges:,} edges could not be oriented consistently (non-orientable).")
        return " ".join(parts)


@dataclass(frozen=True)
class VertexFaces:
    """The triangles around each vertex, packed (CSR): vertex ``i`` has ``indices[offsets[i]:offsets[i + 1]]``.

    Attributes
    ----------
    offsets : (n + 1,) int
    indices : (3 m,) int
        Triangle indices, ascending within each vertex.
    """

    offsets: np.ndarray
    indices: np.ndarray

    def __getitem__(self, vertex: int) -> np.ndarray:
        return self.indices[self.offsets[vertex] : self.offsets[vertex + 1]]

    def __len__(self) -> int:
        return len(self.offsets) - 1


@dataclass(frozen=True, eq=False)
class Mesh:
    """A cleaned triangle mesh with the map back to the file it came from.

    Build one with :func:`recon.load_mesh` or :func:`recon.clean_mesh`; indices stay stable from here on.

    Attributes
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
        Vertex indices, counter-clockwise seen from outside: consistently oriented per component,
        outward (positive signed volume) where the component is closed.
    source_face : (m,) int
        For every triangle, its index in the input's triangle order (ascending: kept triangles keep
        their input order); -1 for a triangle added to close a hole (:func:`recon.mesh.close_holes`).
    n_input_faces : int
    component : (m,) int
        Edge-connected body of each triangle, numbered in order of each body's first triangle.
    report : CleanReport
    """

    vertices: np.ndarray
    faces: np.ndarray
    source_face: np.ndarray
    n_input_faces: int
    component: np.ndarray
    report: CleanReport

    def __repr__(self) -> str:
        return f"Mesh(vertices={len(self.vertices)}, faces={len(self.faces)}, components={self.report.components})"

    # -- per triangle --------------------------------------------------------------------------------------

    @cached_property
    def _cross(self) -> np.ndarray:
        V, F = self.vertices, self.faces
        return np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])

    @property
    def face_cross(self) -> np.ndarray:
        """(m, 3) float: ``(v1 − v0) × (v2 − v0)`` of every triangle (twice its area long), made once and shared
        (the decomposition's :class:`recon.features.FaceGeometry` starts from it)."""
        return self._cross

    @cached_property
    def face_areas(self) -> np.ndarray:
        """(m,) float: triangle areas."""
        return 0.5 * row_norms(self._cross)  # np.linalg.norm(axis=1), bit for bit

    @cached_property
    def face_normals(self) -> np.ndarray:
        """(m, 3) float: unit normals (right-hand rule on ``faces``); zero for a triangle of zero area."""
        norm = 2.0 * self.face_areas
        ok = norm > 0
        if ok.all():  # (a cleaned mesh has no zero-area triangle: the same quotients without the masked copies)
            return self._cross / norm[:, None]
        out = np.zeros_like(self._cross)
        out[ok] = self._cross[ok] / norm[ok, None]
        return out

    @cached_property
    def face_centroids(self) -> np.ndarray:
        """(m, 3) float: mean of each triangle's corners."""
        # vertices[faces].mean(axis=1) bit for bit: numpy adds the three corners in order and divides by 3; by
        # columns (its reduction along an axis of 3 costs ~5x as much)
        V, F = self.vertices, self.faces
        return ((V[F[:, 0]] + V[F[:, 1]]) + V[F[:, 2]]) / 3

    @property
    def area(self) -> float:
        """Total surface area."""
        return float(self.face_areas.sum())

    @property
    def volume(self) -> float:
        """Signed enclosed volume (divergence theorem); meaningful where components are closed."""
        v = self.vertices[self.faces] - self.vertices.mean(axis=0)
        # a tetrahedron's volume is a sixth of its triple product (geometry)
        return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0)

    # -- edges and adjacency --------------------------------------------------------------------------------

    @cached_property
    def _edges(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        from ._topology import unique_edges

        return unique_edges(self.faces, len(self.vertices))

    @property
    def edges_unique(self) -> np.ndarray:
        """(k, 2) int: every edge once, as ``(low, high)`` vertex indices, sorted."""
        return self._edges[0]

    @property
    def face_edges(self) -> np.ndarray:
        """(m, 3) int: index into ``edges_unique`` of edge ``(faces[:, i], faces[:, (i + 1) % 3])``."""
        return self._edges[1]

    @property
    def edge_face_count(self) -> np.ndarray:
        """(k,) int: triangles on each edge (1 boundary, 2 manifold, 3+ non-manifold)."""
        return self._edges[2]

    @cached_property
    def _adjacency(self) -> tuple[np.ndarray, np.ndarray]:
        from ._topology import manifold_pairs

        pairs, edge = manifold_pairs(self.face_edges, self.edge_face_count)
        return pairs, edge

    @property
    def face_adjacency(self) -> np.ndarray:
        """(p, 2) int: pairs of triangles sharing a manifold edge (non-manifold edges give no pair)."""
        return self._adjacency[0]

    @property
    def face_adjacency_edge(self) -> np.ndarray:
        """(p,) int: index into ``edges_unique`` of the edge each ``face_adjacency`` pair shares."""
        return self._adjacency[1]

    @property
    def face_adjacency_edges(self) -> np.ndarray:
        """(p, 2) int: the vertex pair each ``face_adjacency`` pair shares."""
        return self.edges_unique[self.face_adjacency_edge]

    @cached_property
    def vertex_faces(self) -> VertexFaces:
        """Triangles around each vertex, packed (CSR)."""
        flat = self.faces.ravel()
        order = np.argsort(flat, kind="stable")
        offsets = np.zeros(len(self.vertices) + 1, dtype=np.int64)
        np.cumsum(np.bincount(flat, minlength=len(self.vertices)), out=offsets[1:])
        return VertexFaces(offsets=offsets, indices=(order // 3).astype(np.int64))

    # -- scale -----------------------------------------------------------------------------------------------

    @cached_property
    def bounds(self) -> np.ndarray:
        """(2, 3) float: ``[[xmin, ymin, zmin], [xmax, ymax, zmax]]``."""
        return np.array([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    @property
    def diagonal(self) -> float:
        """Length of the bounding-box diagonal."""
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    @cached_property
    def mean_edge_length(self) -> float:
        """Mean length over ``edges_unique``."""
        e = self.edges_unique
        return float(np.linalg.norm(self.vertices[e[:, 0]] - self.vertices[e[:, 1]], axis=1).mean())

    # -- interop ---------------------------------------------------------------------------------------------

    def to_trimesh(self) -> trimesh.Trimesh:
        """A ``trimesh.Trimesh`` on the same arrays, built with ``process=False`` so no index moves."""
        import trimesh

        return trimesh.Trimesh(vertices=self.vertices, faces=self.faces, process=False)
