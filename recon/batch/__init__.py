"""Many meshes to B-reps on a Dask cluster (``recon batch``, :func:`convert_many`): one machine or many.

Needs the ``batch`` extra (``pip install "recon[batch]"``: distributed, fsspec).
"""

from ._inputs import Part, find_parts, name_parts
from ._run import BatchProgress, convert_many
from ._summary import BatchRow

__all__ = ["BatchProgress", "BatchRow", "Part", "convert_many", "find_parts", "name_parts"]
