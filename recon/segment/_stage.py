"""The segment stage: the decomposition's parts refined into the B-rep's faces by a list of passes, each
``(labels, fits, ctx) -> labels``, run by one loop that tidies the labels and refits the faces after every pass
that changed something."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable, Union

import numpy as np

from ..decompose import Decomposition
from ..mesh import Mesh
from ._context import SegmentContext, fit_parts
from ._grow import dissolve_explained, dissolve_misfits, grow_faces
from ._merge import merge_round_bands, merge_same_surface
from ._sharp import face_labels
from ._split import split_unfitted, trim_to_surface
from ._tidy import cut_unbounded, tidy

__all__ = ["PASSES", "Pass", "Rounds", "describe", "refine", "segment"]

log = logging.getLogger(__name__)

#: ``(labels, fits, ctx) -> labels``: the labels itself when the pass changed nothing.
PassFn = Callable[[np.ndarray, dict, SegmentContext], np.ndarray]

#: Rounds of growing the faces over their boundaries, refitting them in between (Lloyd's alternation): the moves
#: of a round change the surfaces the next round's moves are judged by; a few settle it.
GROW_ROUNDS = 3


@dataclass(frozen=True)
class Pass:
    """One pass: ``run(labels, fits, ctx)`` returns new labels, or ``labels`` itself when it changed nothing."""

    run: PassFn

    @property
    def name(self) -> str:
        return self.run.__name__


@dataclass(frozen=True)
class Rounds:
    """Up to ``times`` rounds of ``passes`` in order; the rounds end when the first pass changes nothing."""

    times: int
    passes: tuple[Pass, ...]


Step = Union[Pass, Rounds]

#: The passes in the order they run (``print(describe())`` lists them).
PASSES: tuple[Step, ...] = (
    Pass(merge_same_surface),
    Pass(split_unfitted),
    Pass(trim_to_surface),
    Rounds(GROW_ROUNDS, (Pass(grow_faces), Pass(trim_to_surface), Pass(merge_same_surface))),
    Rounds(1, (Pass(dissolve_misfits), Pass(merge_same_surface))),
    Pass(dissolve_explained),
    Pass(merge_round_bands),
    Pass(cut_unbounded),
)


def describe(passes: tuple[Step, ...] = PASSES) -> str:
    """The order of the passes, one line each."""
    lines = []
    for step in passes:
        if isinstance(step, Rounds):
            names = ", ".join(p.name for p in step.passes)
            lines.append(f"up to {step.times} × ({names}), while {step.passes[0].name} changes something")
        else:
            lines.append(step.name)
    return "\n".join(lines)


#: ``progress(done, total, what)``: a stage's items as they complete (see :func:`recon.convert`'s ``progress``).
Tick = Callable[[int, int, str], None]


def segment(mesh: Mesh, dec: Decomposition, *, tolerance: float, progress: Tick | None = None
            ) -> tuple[np.ndarray, dict]:
    """The face label of every triangle and the surface of every face (the fit stage of :func:`recon.convert`).

    Parameters
    ----------
    mesh : Mesh
    dec : Decomposition
        The decomposition of ``mesh``; its noise σ decides whether the mesh is noise-free.
    tolerance : float
    progress : callable(done, total, what), optional
        Told the parts fitted, then the refinement passes run.

    Returns
    -------
    labels : (m,) int
        Face labels 0..k−1.
    fits : dict of int → SurfaceFit
    """
    ctx = SegmentContext.of(mesh, tolerance, sigma=float(dec.noise))
    labels = face_labels(dec, ctx)
    return refine(labels, fit_parts(labels, ctx, progress=progress), ctx, progress=progress)


def refine(labels: np.ndarray, fits: dict, ctx: SegmentContext, passes: tuple[Step, ...] = PASSES, *,
           progress: Tick | None = None) -> tuple[np.ndarray, dict]:
    """Run ``passes`` over ``labels`` (with their ``fits``): after every pass that changed the labels they are
    tidied (:func:`recon.segment.tidy`) and every face refitted. Returns the final labels and fits.
    ``progress(done, total, "refinement passes")`` counts the passes, rounds not run as if run."""
    budget = [s.times * len(s.passes) if isinstance(s, Rounds) else 1 for s in passes]
    total, done = sum(budget), 0
    for step, n in zip(passes, budget):
        if isinstance(step, Rounds):
            for r in range(step.times):
                changed, labels, fits = _run(step.passes[0], labels, fits, ctx)
                if not changed:
                    break
                for p in step.passes[1:]:
                    _, labels, fits = _run(p, labels, fits, ctx)
                if progress is not None:
                    progress(done + (r + 1) * len(step.passes), total, "refinement passes")
        else:
            _, labels, fits = _run(step, labels, fits, ctx)
        done += n
        if progress is not None:
            progress(done, total, "refinement passes")
    return labels, fits


def _run(step: Pass, labels: np.ndarray, fits: dict, ctx: SegmentContext) -> tuple[bool, np.ndarray, dict]:
    new = step.run(labels, fits, ctx)
    if new is labels:
        return False, labels, fits
    log.debug("pass %s changed %d triangles", step.name, int((new != labels).sum()))
    labels = tidy(new, ctx)
    return True, labels, fit_parts(labels, ctx)
