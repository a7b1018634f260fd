"""The instance step of a map: 3D instances of the scene cloud from what every frame's masks say of it
(:mod:`.observation`), one owner for every method that maps with the reconstruction.

A method's config holds an :class:`InstanceConfig` (voting the dataset masks, view-consensus
clustering of a segmenter's, both in :mod:`.lifting`), or a :class:`GroupedInstanceConfig`, which
groups a segmenter's masks as it chooses and repairs the result (:mod:`.affinity_grouping`,
:mod:`.instance_repair`); :func:`label_instances` lifts by whichever it is.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from openreloc_bench.config import check_ranges
from openreloc_bench.reconstruction.affinity_grouping import AffinityConfig, lift_by_affinity
from openreloc_bench.reconstruction.gravity import levelling
from openreloc_bench.reconstruction.instance_repair import RepairConfig, repair_instances
from openreloc_bench.reconstruction.lifting import (
    ClusteringConfig,
    VotingConfig,
    instance_sets,
    lift_by_clustering,
    lift_by_voting,
)
from openreloc_bench.reconstruction.observation import FrameObservation


@dataclass
class InstanceConfig:
    """Turning a frame's masks into 3D instances: the dataset masks voted, a segmenter's clustered (the
    settings a method that lifts no other way offers, none it would not read)."""

    min_points: int = 20
    """Instances with fewer scene points are dropped."""
    voting: VotingConfig = field(default_factory=VotingConfig)
    clustering: ClusteringConfig = field(default_factory=ClusteringConfig)

    def __post_init__(self) -> None:
        check_ranges(self, non_negative=("min_points",))

    def group(
        self, points: np.ndarray, obs: list[FrameObservation], up: np.ndarray, cameras: np.ndarray, voxel: float
    ) -> np.ndarray:
        """(N,) label per scene point (0 = none) from a segmenter's masks: view-consensus clustering
        (:func:`.lifting.lift_by_clustering`); the cloud's ``up``, the ``cameras``' centres and the fusion
        ``voxel`` are for :class:`GroupedInstanceConfig`."""
        return lift_by_clustering(points, obs, self.clustering)


@dataclass
class GroupedInstanceConfig(InstanceConfig):
    """:class:`InstanceConfig` with the choice of how a segmenter's masks are grouped, the repair of the
    grouped instances, and the ground truth they are scored against (OpenReLoc's mapping)."""

    gt_box_margin: float = 0.03
    """Ground truth for the instance precision/recall: points within this distance (m) of an object's
    box in ``objects.json`` (see :func:`box_point_labels`); ~1.5 fusion voxels absorbs surface noise."""
    grouping: Literal["affinity", "clustering"] = "affinity"
    """How a segmenter's masks become 3D instances: 'affinity' (neighbouring points held together by
    the views' masks, :mod:`.affinity_grouping`; needs the dense views of a walk-through) or
    'clustering' (view consensus of whole masks, :func:`.lifting.lift_by_clustering`; best with
    ``repair.fill``)."""
    affinity: AffinityConfig = field(default_factory=AffinityConfig)
    repair: RepairConfig = field(default_factory=RepairConfig)
    """Fill and merge of the grouped instances (segmenter masks only)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_ranges(self, non_negative=("gt_box_margin",))

    @property
    def min_mask_points(self) -> int:
        """The smallest 2D mask the chosen grouping trusts (the repair reads the same masks)."""
        return (self.affinity if self.grouping == "affinity" else self.clustering).min_mask_points

    def group(
        self, points: np.ndarray, obs: list[FrameObservation], up: np.ndarray, cameras: np.ndarray, voxel: float
    ) -> np.ndarray:
        """(N,) label per scene point (0 = none) from a segmenter's masks, grouped as ``grouping`` says
        and repaired (:mod:`.instance_repair`) with the views from ``cameras`` (N, 3) centres."""
        # grouping splits objects off horizontal surfaces: it sees the cloud levelled, up along +z
        levelled = points @ levelling(up).T
        if self.grouping == "affinity":
            grouped = lift_by_affinity(levelled, obs, self.affinity, voxel)
        else:
            grouped = lift_by_clustering(levelled, obs, self.clustering)
        return repair_instances(points, grouped, obs, cameras, self.repair, self.min_mask_points)


def label_instances(
    points: np.ndarray,
    obs: list[FrameObservation],
    cfg: InstanceConfig,
    segmented: bool,
    up: np.ndarray,
    cameras: np.ndarray,
    voxel: float,
) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """(N,) instance label per scene point (0 = none) and the instances of at least ``min_points`` points
    (id -> point indices): the dataset masks voted, or, ``segmented``, the segmenter's masks grouped
    (:meth:`InstanceConfig.group`: the cloud's ``up``, the (F, 3) ``cameras``' centres and the fusion
    ``voxel``). The labels keep the smaller instances."""
    labels = cfg.group(points, obs, up, cameras, voxel) if segmented else lift_by_voting(len(points), obs, cfg.voting)
    return labels, instance_sets(labels, cfg.min_points)
