"""Agreement of a decomposition with ground-truth faces (area IoU per true face)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..errors import InputError

__all__ = ["FaceRecovery", "face_recovery"]


@dataclass(frozen=True)
class FaceRecovery:
    """Per true face: the part overlapping it most and their area IoU.

    Attributes
    ----------
    true_ids : (t,) int
        True face ids (ascending).
    best_part : (t,) int
        The part with the largest overlap area with each true face.
    iou : (t,) float
        Area of (true face ∩ part) / area of (true face ∪ part).
    threshold : float
        IoU at which a face counts as recovered.
    """

    true_ids: np.ndarray
    best_part: np.ndarray
    iou: np.ndarray
    threshold: float

    @property
    def recovered(self) -> float:
        """Share of true faces with IoU ≥ threshold."""
        return float((self.iou >= self.threshold).mean()) if len(self.iou) else 0.0

    @property
    def mean_iou(self) -> float:
        return float(self.iou.mean()) if len(self.iou) else 0.0


def face_recovery(labels: npt.ArrayLike, true_labels: npt.ArrayLike, areas: npt.ArrayLike, *, threshold: float = 0.5) -> FaceRecovery:
    """For each true face, the part overlapping it most and their area IoU.

    Parameters
    ----------
    labels : (m,) int
        Part id per triangle.
    true_labels : (m,) int
        True face id per triangle; negative ids are ignored (unknown truth).
    areas : (m,) float
        Triangle areas.
    threshold : float
        IoU at which a true face counts as recovered.

    Returns
    -------
    FaceRecovery
    """
    labels = np.asarray(labels)
    true_labels = np.asarray(true_labels)
    areas = np.asarray(areas, dtype=float)
    if labels.ndim != 1 or true_labels.shape != labels.shape or areas.shape != labels.shape:
        raise InputError(
            f"`labels`, `true_labels` and `areas` must be (m,) arrays of one length, got "
            f"{labels.shape}, {true_labels.shape}, {areas.shape}"
        )
    ok = true_labels >= 0
    lab, tru, w = labels[ok].astype(np.int64), true_labels[ok].astype(np.int64), areas[ok]
    t_ids, t_inv = np.unique(tru, return_inverse=True)
    p_ids, p_inv = np.unique(lab, return_inverse=True)
    nt, npart = len(t_ids), len(p_ids)
    inter = np.zeros((nt, npart))
    np.add.at(inter, (t_inv, p_inv), w)
    t_area = inter.sum(axis=1)
    p_area = inter.sum(axis=0)
    best = inter.argmax(axis=1) if npart else np.zeros(nt, np.int64)
    i = inter[np.arange(nt), best]
    iou = i / (t_area + p_area[best] - i)
    return FaceRecovery(true_ids=t_ids, best_part=p_ids[best], iou=iou, threshold=float(threshold))
