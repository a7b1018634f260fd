"""GOReloc's pose search: RANSAC over triples of graph-consistent matches, P3P from box centres to
ellipsoid centres, NGWD scoring, inlier selection and the final P3P / LM.

Per iteration, three frame nodes with candidates are drawn; up to ``hypotheses_per_iteration``
matchings are drawn for them in at most ``tries_per_iteration`` tries, each node taking a random
candidate that agrees on adjacency with the nodes matched before it (an edge between two frame
nodes if and only if one between their map nodes; the adjacency matrices are symmetric, so the
order of the pair does not matter, unlike in GOReloc's code). Each matching gives up to four P3P
poses (``cv2.solveP3P``); poses that put a matched centre behind the camera are rejected and the one
whose projected ellipsoids best fit the detections' box ellipses is kept, if its cost, the sum of
``1 - NGWD`` over the three, is at most ``max_cost``. Inliers are then counted over every frame
node; the hypothesis with most inliers wins and is refined on them.

Where GOReloc's code is loose, the intent is kept: the three nodes are distinct (its sampling may
draw a node twice and waste the iteration), a candidate must agree with every node matched before
it (its code accepts agreement with any one, and may match one map object twice), and inliers are
one-to-one (a greedy assignment by error instead of its per-frame claim flags, which let a later
node take an object without releasing the earlier node's match).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from baselines.goreloc.ellipsoid import ngwd, project_quadrics, projection_matrix
from openreloc_bench import config as cfglib
from openreloc_bench import geometry


@dataclass
class RansacConfig:
    """GOReloc's pose search settings (its code's values)."""

    iterations: int = 30
    """Triples of frame nodes drawn."""
    hypotheses_per_iteration: int = 10
    """At most this many matchings of one triple are evaluated..."""
    tries_per_iteration: int = 50
    """...found in at most this many draws (a draw fails when no candidate agrees on adjacency)."""
    ngwd_scale: float = 100.0
    """NGWD = exp(-W2 / ngwd_scale), W2 the Wasserstein distance of the ellipses (pixels)."""
    max_cost: float = 2.0
    """A P3P pose is a hypothesis when the sum of 1 - NGWD over its three matches is at most this."""
    inlier_error: float = 0.5
    """A (frame node, candidate) pair is an inlier of a pose when 1 - NGWD is at most this."""
    lm_iterations: int = 10
    """Final refinement with more than three inliers: Levenberg-Marquardt on the reprojection of the
    ellipsoid centres to the box centres, this many iterations..."""
    lm_more_iterations: int = 20
    """...then, without the matches whose weighted squared error exceeds ``lm_chi2``, this many more
    (if at least three matches are left; otherwise the RANSAC pose stands)."""
    lm_chi2: float = 5.91
    """Outlier threshold on the weighted squared reprojection error (px^2), the weight being
    1 / frequency of the object's label among its detections."""

    def __post_init__(self) -> None:
        cfglib.check_ranges(
            self,
            positive=("ngwd_scale", "max_cost", "inlier_error", "lm_chi2"),
            non_negative=("lm_iterations", "lm_more_iterations"),
            at_least_one=("iterations", "hypotheses_per_iteration", "tries_per_iteration"),
        )


@dataclass
class Frame:
    """What the pose search needs of the query's graph."""

    boxes: np.ndarray
    """(N, 4) detection boxes."""
    mu: np.ndarray
    """(N, 2) centres of the ellipses inscribed in the boxes."""
    S: np.ndarray
    """(N, 2, 2) their shape matrices."""
    adjacency: np.ndarray
    """(N, N) symmetric bool frame graph."""
    candidates: list[np.ndarray]
    """Per node, candidate map nodes (indices)."""


@dataclass
class MapGeometry:
    """What the pose search needs of the map."""

    quadrics: np.ndarray
    """(M, 4, 4) dual quadrics."""
    centres: np.ndarray
    """(M, 3) ellipsoid centres."""
    adjacency: np.ndarray
    """(M, M) symmetric bool map graph."""
    weights: np.ndarray
    """(M,) LM weights: 1 / frequency of each object's label."""


@dataclass
class Search:
    """The outcome of the pose search."""

    T_wc: np.ndarray | None = None
    matches: dict[int, int] = field(default_factory=dict)
    """Frame node -> map node of the winning hypothesis' inliers."""
    final: str = ""
    """How the returned pose was obtained: 'lm', 'p3p' (three inliers) or 'ransac' (the hypothesis)."""
    hypotheses: int = 0
    """Distinct matchings whose P3P pose passed ``max_cost``."""
    matchings: int = 0
    """Distinct matchings evaluated."""


def p3p_poses(points: np.ndarray, pixels: np.ndarray, K: np.ndarray) -> list[np.ndarray]:
    """Camera-to-world poses (up to four) from three 3D points and their pixels (``cv2.solveP3P``)."""
    n, rvecs, tvecs = cv2.solveP3P(
        np.ascontiguousarray(points, np.float64),
        np.ascontiguousarray(pixels, np.float64),
        np.asarray(K, np.float64),
        None,
        flags=cv2.SOLVEPNP_P3P,
    )
    poses = []
    for r, t in zip(rvecs[:n], tvecs[:n]):
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(t))):  # degenerate configurations
            continue
        T_cw = geometry.make_pose(cv2.Rodrigues(r)[0], np.ravel(t))
        poses.append(geometry.invert(T_cw))
    return poses


def _depths(T_wc: np.ndarray, points: np.ndarray) -> np.ndarray:
    return (points - T_wc[:3, 3]) @ T_wc[:3, 2]


def best_p3p(
    frame: Frame, world: MapGeometry, pairs: list[tuple[int, int]], K: np.ndarray, scale: float
) -> tuple[np.ndarray | None, float]:
    """The P3P pose of three (frame node, map node) pairs whose projected ellipsoids best fit the
    detections, and its cost (sum of 1 - NGWD); (None, 3) when every solution puts a centre behind."""
    u, o = np.array(pairs).T
    best: tuple[np.ndarray | None, float] = (None, 3.0)
    for T in p3p_poses(world.centres[o], frame.mu[u], K):
        if np.any(_depths(T, world.centres[o]) < 0):
            continue
        mu, S, valid = project_quadrics(world.quadrics[o], projection_matrix(K, T))
        cost = float(np.sum(1.0 - np.where(valid, ngwd(mu, S, frame.mu[u], frame.S[u], scale), 0.0)))
        if cost < best[1]:
            best = (T, cost)
    return best


class _Inliers:
    """Inlier counting of a pose over every (frame node, candidate) pair, with the pairs precomputed."""

    def __init__(self, frame: Frame, world: MapGeometry, K: np.ndarray, cfg: RansacConfig):
        self.node = np.concatenate([np.full(len(c), u) for u, c in enumerate(frame.candidates)]).astype(np.int64)
        self.obj = np.concatenate(frame.candidates).astype(np.int64)
        self.objects, self.slot = np.unique(self.obj, return_inverse=True)
        self.frame, self.world, self.K, self.cfg = frame, world, K, cfg

    def __call__(self, T_wc: np.ndarray) -> dict[int, int]:
        mu, S, valid = project_quadrics(self.world.quadrics[self.objects], projection_matrix(self.K, T_wc))
        s = self.slot
        err = 1.0 - ngwd(mu[s], S[s], self.frame.mu[self.node], self.frame.S[self.node], self.cfg.ngwd_scale)
        ok = valid[s] & (err <= self.cfg.inlier_error)
        matches: dict[int, int] = {}
        taken: set[int] = set()
        for k in np.flatnonzero(ok)[np.argsort(err[ok], kind="stable")]:
            u, o = int(self.node[k]), int(self.obj[k])
            if u not in matches and o not in taken:
                matches[u] = o
                taken.add(o)
        return matches


def draw_matchings(
    frame: Frame, world: MapGeometry, nodes: np.ndarray, cfg: RansacConfig, rng: np.random.Generator
) -> list[tuple[tuple[int, int], ...]]:
    """The matchings of one iteration's three ``nodes`` (a list; repeats count, as in GOReloc)."""
    found: list[tuple[tuple[int, int], ...]] = []
    for _ in range(cfg.tries_per_iteration):
        if len(found) >= cfg.hypotheses_per_iteration:
            break
        chosen: list[tuple[int, int]] = []
        for u in nodes:
            ok = [
                o
                for o in frame.candidates[u]
                if all(o != p and frame.adjacency[u, v] == world.adjacency[o, p] for v, p in chosen)
            ]
            if not ok:
                break
            chosen.append((int(u), int(ok[rng.integers(len(ok))])))
        if len(chosen) == len(nodes):
            found.append(tuple(chosen))
    return found


def search_pose(frame: Frame, world: MapGeometry, K: np.ndarray, cfg: RansacConfig, rng: np.random.Generator) -> Search:
    """GOReloc's RANSAC and final refinement (see the module docstring)."""
    out = Search()
    usable = np.array([u for u, c in enumerate(frame.candidates) if len(c)])
    if len(usable) < 3:
        return out
    inliers_of = _Inliers(frame, world, K, cfg)
    seen: dict[frozenset, tuple[np.ndarray | None, dict[int, int]]] = {}
    best: tuple[np.ndarray | None, dict[int, int]] = (None, {})
    for _ in range(cfg.iterations):
        nodes = rng.choice(usable, 3, replace=False)
        for pairs in draw_matchings(frame, world, nodes, cfg, rng):
            key = frozenset(pairs)
            if key not in seen:  # a repeated matching gives the same pose and inliers: evaluate once
                T, cost = best_p3p(frame, world, list(pairs), K, cfg.ngwd_scale)
                hypothesis = T is not None and cost <= cfg.max_cost
                seen[key] = (T, inliers_of(T)) if hypothesis else (None, {})
                out.hypotheses += hypothesis
            T, matches = seen[key]
            if T is not None and len(matches) > len(best[1]):
                best = (T, matches)
    out.matchings = len(seen)
    T, matches = best
    if T is None:
        return out
    out.matches = matches
    out.T_wc, out.final = _refine(frame, world, K, T, matches, cfg)
    return out


def _refine(
    frame: Frame, world: MapGeometry, K: np.ndarray, T: np.ndarray, matches: dict[int, int], cfg: RansacConfig
) -> tuple[np.ndarray, str]:
    """GOReloc's final step on the winning inliers: P3P again for exactly three, LM for more."""
    pairs = sorted(matches.items())
    if len(pairs) == 3:
        T3, _ = best_p3p(frame, world, pairs, K, cfg.ngwd_scale)
        return (T3, "p3p") if T3 is not None else (T, "ransac")
    if len(pairs) < 3:
        return T, "ransac"
    u, o = np.array(pairs).T
    X, x, w = world.centres[o], frame.mu[u], world.weights[o]
    T_cw = geometry.invert(T)
    rvec, tvec = cv2.Rodrigues(T_cw[:3, :3])[0], T_cw[:3, 3].reshape(3, 1).copy()
    rvec, tvec = _lm(X, x, K, rvec, tvec, cfg.lm_iterations)
    keep = w * _sq_errors(X, x, K, rvec, tvec) <= cfg.lm_chi2
    if keep.sum() < 3:
        return T, "ransac"
    X, x, w = X[keep], x[keep], w[keep]
    rvec, tvec = _lm(X, x, K, rvec, tvec, cfg.lm_more_iterations)
    if not np.any(w * _sq_errors(X, x, K, rvec, tvec) < cfg.lm_chi2):
        return T, "ransac"
    return geometry.invert(geometry.make_pose(cv2.Rodrigues(rvec)[0], tvec.ravel())), "lm"


def _lm(X: np.ndarray, x: np.ndarray, K: np.ndarray, rvec: np.ndarray, tvec: np.ndarray, iterations: int):
    """``cv2.solvePnPRefineLM`` for a fixed number of iterations (unweighted: OpenCV's LM takes no
    weights; the label-frequency weights enter the outlier test, and are all 1 on the oracle track)."""
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, iterations, 1e-12)
    return cv2.solvePnPRefineLM(
        np.ascontiguousarray(X, np.float64), np.ascontiguousarray(x, np.float64), K, None, rvec, tvec, criteria
    )


def _sq_errors(X: np.ndarray, x: np.ndarray, K: np.ndarray, rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    proj, _ = cv2.projectPoints(np.ascontiguousarray(X, np.float64), rvec, tvec, K, None)
    return np.sum((proj.reshape(-1, 2) - x) ** 2, axis=1)
