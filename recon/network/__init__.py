"""The curve network: the B-rep's vertices, edges and face loops, from a labelled mesh, placed on its surfaces.

Three steps, the first two here:

- the graph (:func:`curve_network`): boundaries between differently labelled triangles chained into vertices,
  edges and loops, before any CAD kernel;
- the placement (:func:`network_geometry`): vertices to the meeting point of their surfaces, edge polylines onto
  the intersection of their two surfaces;
- the edge fit (:func:`recon.fit.fit_edge_curve`): a line, circle or B-spline pinned at the edge's end vertices.

numpy/scipy only; the surfaces come in as projection callables.
"""

from ._graph import OUTSIDE, CurveNetwork, curve_network
from ._placement import NetworkGeometry, meeting_point, network_geometry

__all__ = [
    "CurveNetwork",
    "NetworkGeometry",
    "OUTSIDE",
    "curve_network",
    "meeting_point",
    "network_geometry",
]
