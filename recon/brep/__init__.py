"""B-rep stage: the only package that imports build123d / OCP (see shared/DESIGN.md)."""

__all__: list[str] = []
