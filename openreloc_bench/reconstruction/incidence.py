"""Sparse 0/1 incidence matrices over the scene points: the masks of every view, what each frame sees,
point sets. View-consensus clustering, instance repair and instance scoring count with their products
instead of Python loops."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


def incidence(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]) -> sp.csr_matrix:
    """float32 CSR with 1 at every (row, col); duplicates collapse to 1."""
    m = sp.csr_matrix((np.ones(len(rows), np.float32), (rows, cols)), shape=shape)
    m.data[:] = 1.0
    return m


def sets_matrix(sets: list[np.ndarray], n_points: int) -> sp.csr_matrix:
    """(sets x points) incidence of point index sets."""
    rows = np.concatenate([np.full(len(s), i) for i, s in enumerate(sets)] or [np.zeros(0, np.int64)])
    return incidence(rows, np.concatenate(sets or [np.zeros(0, np.int64)]), (len(sets), n_points))


@dataclass
class ViewEvidence:
    """The masks of every view as sparse incidences over the scene points."""

    masks: sp.csr_matrix
    """(masks x points) 1 where a mask holds a point."""
    mask_frame: np.ndarray
    """(masks,) the observation each mask belongs to."""
    seen: sp.csr_matrix
    """(observations x points) 1 where a frame sees a point."""


def view_evidence(n_points: int, obs: list, min_mask_points: int) -> ViewEvidence:
    """Incidences of the observations' masks (those with at least ``min_mask_points`` seen points) and of
    what each observation sees (``obs``: :class:`.observation.FrameObservation`)."""
    rows, cols, frame_of = [], [], []
    for f, o in enumerate(obs):
        for m in o.masks:
            if len(m) >= min_mask_points:
                rows.append(np.full(len(m), len(frame_of)))
                cols.append(o.point_idx[m])
                frame_of.append(f)
    empty = np.zeros(0, np.int64)
    masks = incidence(np.concatenate(rows or [empty]), np.concatenate(cols or [empty]), (len(frame_of), n_points))
    seen = incidence(
        np.concatenate([np.full(len(o.point_idx), f) for f, o in enumerate(obs)] or [empty]),
        np.concatenate([o.point_idx for o in obs] or [empty]),
        (len(obs), n_points),
    )
    return ViewEvidence(masks, np.array(frame_of, np.int64), seen)
