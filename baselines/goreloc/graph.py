"""GOReloc's object graphs and their semantic node descriptors (graph kernels over COCO labels).

Both graphs are symmetric boolean adjacency matrices. GOReloc stores an edge once, keyed by its
ordered node pair, and looks edges up with the pair in whatever order it comes, so about half of
the adjacency checks of its sampling answer "no edge" for connected nodes. A symmetric matrix
answers ``adj[a, b] == adj[b, a]`` by construction: that bug cannot occur here.

Descriptors (80 bins, one per COCO class, L2-normalised):
- frame node: each neighbour adds ``1 - share of the frame's nodes with its label`` to its label's bin
  (rare labels weigh more);
- map node: the sum of its neighbours' label-frequency vectors (an object's distribution over the
  labels it was detected with). GOReloc stores these frequencies only for objects seen with more than
  one label, so single-label neighbours add nothing and most map descriptors are empty or nearly so;
  here a single-label object has frequency 1 for its label (the fix of that second bug).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from baselines.goreloc.vocabulary import N_CLASSES


def knn_adjacency(points: np.ndarray, k: int) -> np.ndarray:
    """(N, N) symmetric bool adjacency: every point linked to its ``min(k, N - 1)`` nearest others."""
    pts = np.asarray(points, dtype=np.float64)
    n = len(pts)
    adj = np.zeros((n, n), bool)
    k = min(k, n - 1)
    if k <= 0:
        return adj
    _, idx = cKDTree(pts).query(pts, k=k + 1)
    for i, row in enumerate(idx):
        nbrs = [j for j in row if j != i][:k]  # coincident points may put i itself later in its row
        adj[i, nbrs] = True
    return adj | adj.T


def _unit_rows(x: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(x, axis=1, keepdims=True)
    return np.divide(x, norm, out=np.zeros_like(x), where=norm > 0)


def frame_descriptors(labels: np.ndarray, adjacency: np.ndarray) -> np.ndarray:
    """(N, 80) descriptors of a frame graph's nodes (labels: (N,) COCO ids)."""
    labels = np.asarray(labels, dtype=np.int64)
    share = np.bincount(labels, minlength=N_CLASSES) / max(len(labels), 1)
    onehot = np.zeros((len(labels), N_CLASSES))
    onehot[np.arange(len(labels)), labels] = 1.0 - share[labels]
    return _unit_rows(adjacency.astype(np.float64) @ onehot)


def label_frequencies(counts: np.ndarray) -> np.ndarray:
    """(N, 80) each object's share of detections per label (a single-label object: 1 for its label)."""
    counts = np.asarray(counts, dtype=np.float64)
    total = counts.sum(axis=1, keepdims=True)
    return np.divide(counts, total, out=np.zeros_like(counts), where=total > 0)


def map_descriptors(frequencies: np.ndarray, adjacency: np.ndarray) -> np.ndarray:
    """(N, 80) descriptors of the map graph's nodes: sum of the neighbours' label frequencies."""
    return _unit_rows(adjacency.astype(np.float64) @ frequencies)


def match_candidates(
    frame_labels: np.ndarray,
    frame_desc: np.ndarray,
    map_labels: np.ndarray,
    map_desc: np.ndarray,
    min_cosine: float,
    top_k: int,
) -> list[np.ndarray]:
    """Per frame node, the map nodes filed under its label whose descriptor cosine exceeds
    ``min_cosine``, best first, at most ``top_k`` (indices into the map's nodes)."""
    cos = frame_desc @ map_desc.T  # both L2-normalised (or zero)
    same = np.asarray(frame_labels)[:, None] == np.asarray(map_labels)[None, :]
    cos = np.where(same, cos, -np.inf)
    out = []
    for row in cos:
        order = np.argsort(-row, kind="stable")[:top_k]
        out.append(order[row[order] > min_cosine])
    return out
