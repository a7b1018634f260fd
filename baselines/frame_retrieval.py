"""Per-scene global image retrieval over local features: VLAD and a bag-of-words vocabulary tree.

Both are learned on the mapping frames of one scene (no pretrained model here):

- :class:`Vlad` -- k-means centres over float descriptors (e.g. RootSIFT); an image is the sum of
  its descriptors' residuals to their nearest centre, intra-normalised per centre then L2-normalised
  (Arandjelovic & Zisserman, "All about VLAD", 2013); images compare by cosine.
- :class:`VocabularyTree` -- hierarchical k-means over binary descriptors (e.g. ORB), the DBoW2
  vocabulary of ORB-SLAM2: words are leaves, weighted by TF-IDF, vectors L1-normalised and compared
  with DBoW2's L1 score; the node of each descriptor at a chosen level is its "direct index" entry,
  which restricts descriptor matching to descriptors under the same node.

Each turns into plain arrays (:meth:`to_arrays`) and back, so a method stores it in its map file.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
import scipy.sparse as sp

_POPCOUNT = np.unpackbits(np.arange(256, dtype=np.uint8)[:, None], axis=1).sum(axis=1).astype(np.uint8)
_CHUNK = 50_000  # descriptors per step of a vocabulary descent (bounds its temporary arrays)


def hamming(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamming distances between binary descriptors (uint8 bytes on the last axis), broadcasting."""
    return _POPCOUNT[np.bitwise_xor(a, b)].sum(axis=-1, dtype=np.int32)


def hamming_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)) Hamming distances, as one matrix product on the bits: for bit vectors,
    ``|a xor b| = |a| + |b| - 2 a.b``."""
    if not len(a) or not len(b):
        return np.zeros((len(a), len(b)), np.int32)
    ab = np.unpackbits(a, axis=1).astype(np.float32)
    bb = np.unpackbits(b, axis=1).astype(np.float32)
    return np.rint(ab.sum(1)[:, None] + bb.sum(1)[None, :] - 2 * ab @ bb.T).astype(np.int32)


def _kmeans(data: np.ndarray, k: int, iterations: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV k-means with k-means++ seeding, seeded for reproducible maps."""
    cv2.setRNGSeed(seed)
    criteria = (cv2.TERM_CRITERIA_MAX_ITER | cv2.TERM_CRITERIA_EPS, iterations, 1e-4)
    _, labels, centres = cv2.kmeans(data, k, None, criteria, 1, cv2.KMEANS_PP_CENTERS)
    return centres, labels.ravel()


def _subsample(n: int, limit: int, seed: int) -> np.ndarray:
    return np.arange(n) if n <= limit else np.sort(np.random.default_rng(seed).choice(n, limit, replace=False))


# --------------------------------------------------------------------------------------------
# VLAD
# --------------------------------------------------------------------------------------------


@dataclass
class VladConfig:
    """Vocabulary of :class:`Vlad`."""

    clusters: int = 64
    """Number of k-means centres (VLAD dimension = clusters x descriptor dimension)."""
    training_descriptors: int = 100_000
    """Descriptors sampled from the mapping frames to fit the centres."""
    iterations: int = 20
    """k-means iterations."""
    seed: int = 0
    """Seed of the sampling and of k-means++ (maps are reproducible)."""

    def __post_init__(self) -> None:
        if self.clusters < 1 or self.training_descriptors < self.clusters or self.iterations < 1:
            raise ValueError("need clusters >= 1, training_descriptors >= clusters and iterations >= 1")


class Vlad:
    """VLAD global descriptors over one scene's centres (see the module doc)."""

    def __init__(self, centres: np.ndarray):
        self.centres = np.ascontiguousarray(centres, dtype=np.float32)

    @classmethod
    def fit(
        cls, descriptors: np.ndarray, cfg: VladConfig, preprocess: Callable[[np.ndarray], np.ndarray] = np.asarray
    ) -> Vlad:
        """Centres from a sample of ``descriptors``, each run through ``preprocess`` (e.g. RootSIFT)."""
        sample = preprocess(descriptors[_subsample(len(descriptors), cfg.training_descriptors, cfg.seed)])
        if len(sample) < cfg.clusters:
            raise ValueError(f"{len(sample)} descriptors cannot fit {cfg.clusters} VLAD centres")
        centres, _ = _kmeans(np.ascontiguousarray(sample, np.float32), cfg.clusters, cfg.iterations, cfg.seed)
        return cls(centres)

    def describe(self, descriptors: np.ndarray) -> np.ndarray:
        """(clusters x D,) float32 unit vector of one image (zeros for an image without features)."""
        c = self.centres
        out = np.zeros_like(c)
        if len(descriptors):
            d = descriptors.astype(np.float32)
            nearest = np.argmin((c * c).sum(1)[None, :] - 2 * d @ c.T, axis=1)
            np.add.at(out, nearest, d)
            out -= np.bincount(nearest, minlength=len(c))[:, None] * c
            out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)  # intra-normalisation
        return (out / max(float(np.linalg.norm(out)), 1e-12)).ravel()

    def describe_all(
        self, descriptors: np.ndarray, offsets: np.ndarray, preprocess: Callable[[np.ndarray], np.ndarray] = np.asarray
    ) -> np.ndarray:
        """(F, clusters x D) descriptors of the F images whose rows are ``offsets[f]:offsets[f+1]``."""
        return np.stack([self.describe(preprocess(descriptors[a:b])) for a, b in zip(offsets[:-1], offsets[1:])])

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {"vlad_centres": self.centres}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> Vlad:
        return cls(arrays["vlad_centres"])


def top_k(database: np.ndarray, query: np.ndarray, k: int) -> np.ndarray:
    """Indices of the ``k`` database rows most similar to ``query`` (dot product), best first."""
    scores = database @ query
    k = min(k, len(scores))
    best = np.argpartition(-scores, k - 1)[:k] if k else np.zeros(0, int)
    return best[np.argsort(-scores[best], kind="stable")]


# --------------------------------------------------------------------------------------------
# Vocabulary tree (DBoW2)
# --------------------------------------------------------------------------------------------


@dataclass
class VocabularyConfig:
    """Shape and training of a :class:`VocabularyTree`."""

    branching: int = 10
    """Children per node (DBoW2's k; ORB-SLAM2's ORBvoc uses 10)."""
    depth: int = 4
    """Levels below the root (ORBvoc: 6, trained on millions of images' descriptors; a single scene
    holds a few hundred thousand, enough for about 10^4 words)."""
    training_descriptors: int = 100_000
    """Descriptors sampled from the mapping frames to fit the tree."""
    iterations: int = 10
    """k-means iterations per node."""
    seed: int = 0
    """Seed of the sampling and of k-means++."""

    def __post_init__(self) -> None:
        if self.branching < 2 or self.depth < 1 or self.iterations < 1 or self.training_descriptors < 1:
            raise ValueError("need branching >= 2, depth >= 1, iterations >= 1 and training_descriptors >= 1")
        if self.branching**self.depth > 10**7:
            raise ValueError(f"{self.branching}^{self.depth} words is too many: at most 10^7 (ORBvoc has 10^6)")


class VocabularyTree:
    """A DBoW2-style vocabulary over binary descriptors; see the module doc.

    Nodes are numbered breadth first, node 0 the root; ``children[n]`` lists a node's children
    (-1 padded) and a node without children is a word.
    """

    def __init__(self, centres: np.ndarray, children: np.ndarray, level: np.ndarray, idf: np.ndarray):
        self.centres = centres
        """(nodes, bytes) uint8 binary centre of each node (the root's is unused)."""
        self.children = children
        """(nodes, branching) int32 child node ids, -1 where none."""
        self.level = level
        """(nodes,) int8 depth of each node (root 0)."""
        self.idf = idf
        """(nodes,) float32 inverse document frequency of each word, log(frames / frames with it)."""

    @property
    def n_nodes(self) -> int:
        return len(self.level)

    @classmethod
    def fit(cls, descriptors: np.ndarray, offsets: np.ndarray, cfg: VocabularyConfig) -> VocabularyTree:
        """Hierarchical k-majority on a sample of the descriptors, then IDF over all frames.

        Each node's k-means runs on the descriptors' bits with OpenCV (squared Euclidean distance
        between bit vectors is their Hamming distance), k-means++ seeded; its centres are rounded to
        the bit majority, DBoW2's k-majority centres, and the node's descriptors re-assigned to them
        by Hamming distance, the rule :meth:`transform` descends by.
        """
        sample = descriptors[_subsample(len(descriptors), cfg.training_descriptors, cfg.seed)]
        k, nbytes = cfg.branching, descriptors.shape[1]
        centres, children, level = [np.zeros(nbytes, np.uint8)], [np.full(k, -1, np.int32)], [0]
        queue = [(0, np.arange(len(sample)))]
        while queue:
            node, idx = queue.pop(0)
            if level[node] >= cfg.depth or len(idx) <= 1:
                continue
            kk = min(k, len(idx))
            bits = np.unpackbits(sample[idx], axis=1).astype(np.float32)
            mean, _ = _kmeans(bits, kk, cfg.iterations, cfg.seed + node)
            node_centres = np.packbits(mean > 0.5, axis=1)
            assign = np.argmin(hamming(sample[idx][:, None, :], node_centres[None, :, :]), axis=1)
            for c in range(kk):
                child = len(level)
                centres.append(node_centres[c])
                children.append(np.full(k, -1, np.int32))
                level.append(level[node] + 1)
                children[node][c] = child
                queue.append((child, idx[assign == c]))
        tree = cls(np.stack(centres), np.stack(children), np.array(level, np.int8), np.zeros(len(level), np.float32))
        words, _ = tree.transform(descriptors)
        frames = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets))
        has = np.zeros(tree.n_nodes, np.int64)
        np.add.at(has, np.unique(np.stack([frames, words], 1), axis=0)[:, 1], 1)
        tree.idf = np.log((len(offsets) - 1) / np.maximum(has, 1)).astype(np.float32)
        return tree

    def transform(self, descriptors: np.ndarray, level: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Each descriptor's word and its ancestor node at ``level`` (the direct-index node), both (n,)."""
        if len(descriptors) > _CHUNK:
            parts = [self.transform(descriptors[i : i + _CHUNK], level) for i in range(0, len(descriptors), _CHUNK)]
            return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
        n = len(descriptors)
        node = np.zeros(n, np.int64)
        at_level = node.copy()
        for depth in range(1, int(self.level.max()) + 1):
            kids = self.children[node]
            active = kids[:, 0] >= 0
            if not active.any():
                break
            d = hamming(descriptors[active][:, None, :], self.centres[np.maximum(kids[active], 0)])
            d = np.where(kids[active] >= 0, d, np.iinfo(np.int32).max)
            node[active] = kids[active, np.argmin(d, axis=1)]
            if depth <= level:
                at_level = node.copy()
        return node, at_level

    def bow(self, words: np.ndarray) -> sp.csr_matrix:
        """(1, nodes) TF-IDF vector of one image, L1-normalised (DBoW2's TF_IDF weighting, L1 norm)."""
        return self.bow_matrix(words, np.array([0, len(words)]))

    def bow_matrix(self, words: np.ndarray, offsets: np.ndarray) -> sp.csr_matrix:
        """(F, nodes) TF-IDF vectors of the F images whose words are ``offsets[f]:offsets[f+1]``."""
        counts = np.diff(offsets)
        rows = np.repeat(np.arange(len(counts)), counts)
        tf = 1.0 / np.maximum(counts[rows], 1)
        m = sp.csr_matrix((tf * self.idf[words], (rows, words)), shape=(len(counts), self.n_nodes), dtype=np.float64)
        m.sum_duplicates()
        norm = np.asarray(abs(m).sum(axis=1)).ravel()
        return sp.diags(1.0 / np.maximum(norm, 1e-12)) @ m

    @staticmethod
    def score(database: sp.csr_matrix, query: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
        """DBoW2's L1 score of the query against every database image, and the number of words each
        shares with it. For L1-normalised non-negative vectors ``1 - |v - w|_1 / 2 = sum_i min(v_i, w_i)``."""
        q = query.tocsr()
        sub = database[:, q.indices].toarray()
        return np.minimum(sub, q.data[None, :]).sum(axis=1), (sub > 0).sum(axis=1)

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {
            "voc_centres": self.centres,
            "voc_children": self.children,
            "voc_level": self.level,
            "voc_idf": self.idf,
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> VocabularyTree:
        return cls(arrays["voc_centres"], arrays["voc_children"], arrays["voc_level"], arrays["voc_idf"])
