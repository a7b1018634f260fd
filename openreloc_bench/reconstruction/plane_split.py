"""Splitting objects off the walls, floors and surfaces they were grouped with, by the fused geometry.

A segmenter that never cuts a sink from the wall behind it, or a mug from the cabinet it stands on,
makes every view hold them together, and affinity grouping (:mod:`affinity_grouping`) rightly follows
the views. The masks hold no evidence against such a merge; the depth does, in two ways:

1. **Structural planes** (:func:`split_off_planes`): walls, floors and ceilings are large planes, and
   an object touching one stands out of it. A grouped region that contains a structural plane (at
   least ``min_area`` m^2 of points within ``distance_spacings`` of one plane, spanning at least
   ``min_extent`` m, as the slab filter's walls do) keeps the plane's points, and the rest of it falls
   into the parts connected without them, each a region of its own. Parts too small to stand alone
   are left to affinity grouping's absorption, which gives them to the neighbour the views hold them
   with most (a table's leg cut off by the floor plane returns to the table).
2. **Supports** (:func:`split_off_supported`): small objects stand on the top surface of furniture.
   A region's top is its highest horizontal surface of at least ``min_area`` m^2 (up is +z, the
   generator's and ScanNet's convention); what rises above it in parts smaller than ``max_size``
   becomes regions of its own. Run after the absorption, which would hand such small parts back.

Objects flush with a wall (a painting, a door) lie within the plane's band and stay merged; a large
object's own parts (a chair's back, a bed's headboard) are too large to count as objects it supports.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from openreloc_bench.config import check_ranges


@dataclass
class PlaneSplitConfig:
    """Which planes are structure (walls, floors, ceilings), and how they are found."""

    enabled: bool = True
    """Split grouped regions at their structural planes (off: regions stay as the views grouped them)."""
    min_area: float = 2.0
    """A plane is structural with at least this many m^2 of points (at the point spacing) in its band."""
    min_extent: float = 2.5
    """...spanning at least this length (m) in the plane (the slab filter's wall length)."""
    distance_spacings: float = 1.5
    """Points within this many point spacings of a plane are its points (its band)."""
    max_planes: int = 4
    """At most this many structural planes per region (a corner holds two walls and a floor)."""
    iterations: int = 300
    """RANSAC samples per plane."""
    sample_points: int = 4000
    """Samples are scored on this many of the region's points (the winner is refitted on all)."""

    def __post_init__(self) -> None:
        check_ranges(
            self,
            positive=("min_area", "min_extent", "distance_spacings"),
            at_least_one=("max_planes", "iterations", "sample_points"),
        )


@dataclass
class SupportSplitConfig:
    """Small objects standing on a region's top surface."""

    enabled: bool = True
    """Split what stands on a region's top surface off it (off: it stays with its support)."""
    min_area: float = 0.1
    """A region's top is its highest horizontal surface with at least this many m^2 of points."""
    max_size: float = 0.5
    """Parts above the top with a smaller diagonal (m) are objects; larger ones are the region's own
    (a chair's back above its seat). The "small" objects of the map's instance scores."""
    horizontal_degrees: float = 15.0
    """Points whose normal is within this angle of vertical lie on horizontal surfaces."""
    band_spacings: float = 1.5
    """The top surface's points lie within this many point spacings of its height."""

    def __post_init__(self) -> None:
        check_ranges(self, positive=("min_area", "max_size", "band_spacings"), non_negative=("horizontal_degrees",))
        if self.horizontal_degrees >= 90:
            raise ValueError(f"'horizontal_degrees' must be < 90, got {self.horizontal_degrees}")


def split_off_planes(
    points: np.ndarray, regions: np.ndarray, edges: np.ndarray, cfg: PlaneSplitConfig, spacing: float, seed: int = 0
) -> np.ndarray:
    """``regions`` (per point, -1 = none) with every region holding a structural plane split into the
    plane's points (keeping the region's id) and the parts of the rest connected by ``edges`` (pairs of
    neighbouring point indices), numbered after the largest id."""
    if not cfg.enabled or len(points) == 0:
        return regions
    off_plane = np.zeros(len(points), bool)
    min_points = cfg.min_area / spacing**2
    rng = np.random.default_rng(seed)
    ids, counts = np.unique(regions[regions >= 0], return_counts=True)
    for rid in ids[counts >= min_points]:
        idx = np.flatnonzero(regions == rid)
        rest = np.ones(len(idx), bool)
        for _ in range(cfg.max_planes):
            band = _plane_band(points[idx[rest]], cfg, spacing, rng)
            if band is None or band.sum() < min_points or _extent(points[idx[rest]][band]) < cfg.min_extent:
                break
            rest[np.flatnonzero(rest)[band]] = False
        if not rest.all():
            off_plane[idx[rest]] = True
    return _split_parts(regions, edges, off_plane)


def split_off_supported(
    points: np.ndarray, regions: np.ndarray, edges: np.ndarray, cfg: SupportSplitConfig, spacing: float
) -> np.ndarray:
    """``regions`` (per point, -1 = none) with the parts standing on each region's top surface (connected
    by ``edges``, smaller than ``max_size``) made regions of their own, numbered after the largest id."""
    if not cfg.enabled or len(points) == 0:
        return regions
    horizontal = np.abs(point_normals(points)[:, 2]) >= np.cos(np.radians(cfg.horizontal_degrees))
    band = cfg.band_spacings * spacing
    min_points = cfg.min_area / spacing**2
    above = np.zeros(len(points), bool)
    order = np.argsort(regions, kind="stable")
    starts = np.searchsorted(regions[order], np.unique(regions[regions >= 0]))
    for idx in np.split(order, starts)[1:]:
        if horizontal[idx].sum() < min_points:
            continue
        top = _top_height(points[idx[horizontal[idx]], 2], band, min_points)
        if top is not None:
            above[idx[points[idx, 2] > top + band]] = True
    out = _split_parts(regions, edges, above)
    if above.any():  # parts as large as the region's own structure stay with it
        part_ids, inverse = np.unique(out[above], return_inverse=True)
        lo = np.full((len(part_ids), 3), np.inf)
        hi = np.full((len(part_ids), 3), -np.inf)
        np.minimum.at(lo, inverse, points[above])
        np.maximum.at(hi, inverse, points[above])
        back = np.flatnonzero(above)[np.linalg.norm(hi - lo, axis=1)[inverse] >= cfg.max_size]
        out[back] = regions[back]
    return out


def _split_parts(regions: np.ndarray, edges: np.ndarray, cut: np.ndarray) -> np.ndarray:
    """The ``cut`` points of each region regrouped into the parts that ``edges`` connect within the
    region, each a new region numbered after the largest id."""
    out = regions.copy()
    if not cut.any():
        return out
    i, j = edges[:, 0], edges[:, 1]
    keep = cut[i] & cut[j] & (regions[i] == regions[j])
    graph = sp.coo_matrix((np.ones(int(keep.sum())), (i[keep], j[keep])), shape=(len(regions),) * 2)
    _, part = connected_components(graph, directed=False)
    _, new = np.unique(part[cut], return_inverse=True)
    out[cut] = int(regions.max(initial=-1)) + 1 + new.ravel()
    return out


def _plane_band(pts: np.ndarray, cfg: PlaneSplitConfig, spacing: float, rng: np.random.Generator) -> np.ndarray | None:
    """Mask of the points within the band of the best RANSAC plane of ``pts`` (None: too few points).

    Written here rather than with open3d's ``segment_plane``, whose result changes with its thread
    count: maps must not depend on the machine."""
    if len(pts) < 3:
        return None
    tol = cfg.distance_spacings * spacing
    scored = pts[rng.choice(len(pts), cfg.sample_points, replace=False)] if len(pts) > cfg.sample_points else pts
    tri = pts[rng.integers(0, len(pts), (cfg.iterations, 3))]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).astype(np.float64)
    norm = np.linalg.norm(normal, axis=1)
    ok = norm > 1e-9
    if not ok.any():
        return None
    normal, anchor = normal[ok] / norm[ok, None], tri[ok, 0]
    support = (np.abs((scored[None] - anchor[:, None]) @ normal[..., None])[..., 0] < tol).sum(axis=1)
    best = int(np.argmax(support))
    band = np.abs((pts - anchor[best]) @ normal[best]) < tol
    # refit on the band (least squares: the normal is the direction of least spread)
    centre = pts[band].mean(axis=0)
    n = np.linalg.svd(pts[band] - centre, full_matrices=False)[2][-1]
    return np.abs((pts - centre) @ n) < tol


def _extent(pts: np.ndarray) -> float:
    """The longest span (m) of points lying in a plane, along their principal axis."""
    centred = pts - pts.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    return float(np.ptp(centred @ axis))


def point_normals(points: np.ndarray) -> np.ndarray:
    """(N, 3) unit normals of a point cloud from 16 neighbours each (their sign is arbitrary)."""
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points.astype(np.float64)))
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(16))
    return np.asarray(pcd.normals)


def _top_height(z: np.ndarray, band: float, min_points: float) -> float | None:
    """Height of the highest surface: the median of the heights within ``band`` of the highest one that
    has at least ``min_points`` of ``z`` within ``band`` (None: no such surface)."""
    z = np.sort(z)
    count = np.searchsorted(z, z + band, side="right") - np.searchsorted(z, z - band, side="left")
    dense = np.flatnonzero(count >= min_points)
    if not len(dense):
        return None
    highest = z[dense[-1]]
    return float(np.median(z[np.searchsorted(z, highest - band) : np.searchsorted(z, highest + band, side="right")]))
