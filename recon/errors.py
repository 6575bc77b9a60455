"""Errors recon raises. One root, a few children (after shapely's ``errors.py``).

The CLI turns any :class:`ReconError` into one line on stderr and exit code 2 (bad input), but a
:class:`BrepError` in ``recon convert`` into exit code 3 (no result): a mesh recon could not make a B-rep of is
recon's failure; and an :class:`UnwritableError` into exit code 1: a result that is not right, found before a file
was written.
"""

__all__ = [
    "ReconError",
    "InputError",
    "MeshError",
    "DecompositionError",
    "FitError",
    "BrepError",
    "ExportError",
    "UnwritableError",
]


class ReconError(Exception):
    """Root of every error recon raises on purpose."""


class InputError(ReconError, ValueError):
    """A file or argument cannot be used: missing, unreadable, empty, wrong format or shape."""


class MeshError(InputError):
    """A mesh that cannot be processed (no triangles, NaN/inf coordinates, ...)."""


class DecompositionError(ReconError):
    """The skeleton or segment decomposition could not be built."""


class FitError(ReconError):
    """A surface or curve fit was misused (an expected failure is a falsy result, not this)."""


class BrepError(ReconError):
    """OpenCascade could not build, repair or write the B-rep (recon's failure, not the input's: exit code 3)."""


class ExportError(ReconError):
    """A result could not be written."""


class UnwritableError(BrepError):
    """recon's B-rep holds no face a file can carry (faces with no area): nothing was written (exit code 1)."""
