"""The OpenReLoc object-oriented map suite (paper section 3.1) and its on-disk format.

A map is everything OpenReLoc keeps for query time: landmarks (points, 3D box, centre, descriptor),
object-oriented reference frames (pose + landmark 2D boxes, no images), the scene graph and the
mapping camera. On disk (``map_dir``)::

    arrays.npz      landmark points (uint16-quantised offsets in their box), descriptors (float16),
                    reference frames (ragged arrays), graph edges, the landmarks' keypoints
                    (:mod:`.anchors`: world points, product-quantisation codes of their RootSIFT
                    descriptors and the codebook, owning landmark)
    meta.json       format version, camera, encoder/mapping config, stats, per-landmark scalars
    manifest.json   written last: format name + version and the sha256 and size of every file

Loading never needs the mapping frames. A truncated or edited file fails its checksum, and a map of
another format version is refused, each with a :class:`DataError` naming the file. Files are
byte-identical when the same map is saved twice (fixed zip timestamps, sorted JSON).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import networkx as nx
import numpy as np

from openreloc_bench.data import mapfile
from openreloc_bench.errors import DataError
from openreloc_bench.methods import MapPoints
from openreloc_bench.openreloc.anchors import DESCRIPTOR_SIZE, Anchors, DescriptorCodec

MAP_FORMAT_VERSION = 3
"""2: the landmarks' keypoints (anchors) and the world's up; 3: one product-quantised descriptor per anchor."""
MAP_FORMAT_NAME = "openreloc-map"
EDGE_KINDS = ("knn", "overlap")
_POINT_QUANTUM_M = 0.001  # landmark points are stored to 1 mm (coarser only for boxes > 65 m)


@dataclass
class Landmark:
    """One 3D object instance of the map."""

    id: int
    """Landmark id (>= 1); with oracle masks equal to the dataset instance id."""
    points: np.ndarray
    """(N, 3) float32 world points (voxel-downsampled) of the object."""
    box_min: np.ndarray
    """(3,) world axis-aligned box min."""
    box_max: np.ndarray
    """(3,) world axis-aligned box max."""
    center: np.ndarray
    """(3,) centroid of the points."""
    descriptor: np.ndarray
    """(D,) float32 unit vector: mean of the top-k crop embeddings, re-normalised."""
    valid: bool = True
    """False = removed by invalid-object filtering (walls, floors...)."""
    category: str | None = None
    """Ground-truth category when known (diagnostics/explanations only; never used to match)."""
    n_views: int = 0
    """Number of mapping frames that observed it."""


@dataclass
class ReferenceFrame:
    """An object-oriented reference frame: a pose and the 2D boxes of the landmarks it sees."""

    index: int
    """Index of the mapping frame it came from."""
    T_wc: np.ndarray
    """(4, 4) camera-to-world pose."""
    boxes: dict[int, np.ndarray]
    """Landmark id -> [x0, y0, x1, y1] float32 box of its visible projected points."""
    visibility: dict[int, float] = field(default_factory=dict)
    """Landmark id -> share of its points that project inside the image (and are not occluded)."""


@dataclass
class ObjectMap:
    """The whole map suite; :meth:`save` / :meth:`load` give the versioned, checksummed file."""

    landmarks: dict[int, Landmark]
    reference_frames: list[ReferenceFrame]
    graph: nx.Graph
    """Nodes = landmark ids; edge attribute ``kind`` in {"knn", "overlap"}."""
    K: np.ndarray
    """(3, 3) intrinsics of the mapping camera."""
    width: int
    height: int
    encoder: dict[str, Any]
    """The encoder's ``config()`` used for descriptors (the query side must use the same)."""
    config: dict[str, Any]
    """Mapping config as plain data."""
    stats: dict[str, Any]
    """Timings and counts (frames kept/total, skipped frames...), for reports."""
    anchors: Anchors = field(default_factory=Anchors.empty)
    """The landmarks' keypoints (none where the map was built without them)."""
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    """(3,) unit vector: the world's up, as the map builder established it (recordings are not z up)."""

    # ---------------------------------------------------------------------------------------- queries

    def valid_ids(self) -> list[int]:
        """Sorted ids of the landmarks kept by invalid-object filtering."""
        return sorted(i for i, lm in self.landmarks.items() if lm.valid)

    def descriptor_matrix(self, ids: list[int]) -> np.ndarray:
        """(len(ids), D) float32 descriptors, rows in the order of ``ids``."""
        if not ids:
            return np.zeros((0, self.descriptor_dim), dtype=np.float32)
        return np.stack([self.landmarks[i].descriptor for i in ids]).astype(np.float32)

    @property
    def descriptor_dim(self) -> int:
        return next((int(lm.descriptor.shape[0]) for lm in self.landmarks.values()), 0)

    def drawn(self) -> MapPoints:
        """The landmarks' points (one group each; the filtered ones muted) and the reference frames."""
        ids = sorted(self.landmarks)
        lms = [self.landmarks[i] for i in ids]
        counts = [len(lm.points) for lm in lms]
        labels = {
            lid: f"landmark {lid}: {lm.category or 'no category'}<br>"
            f"{'valid' if lm.valid else 'filtered (invalid object)'}, {len(lm.points)} points, "
            f"seen in {lm.n_views} frame{'' if lm.n_views == 1 else 's'}"
            for lid, lm in zip(ids, lms)
        }
        rfs = self.reference_frames
        return MapPoints(
            points=np.concatenate(
                [np.asarray(lm.points, np.float64).reshape(-1, 3) for lm in lms] or [np.zeros((0, 3))]
            ),
            group=np.repeat(np.array(ids, dtype=np.int64), counts),
            labels=labels,
            K=self.K,
            size=(self.width, self.height),
            cameras=np.stack([rf.T_wc for rf in rfs]) if rfs else np.zeros((0, 4, 4)),
            camera_labels=tuple(f"reference frame {rf.index}: {len(rf.boxes)} landmarks in view" for rf in rfs),
            muted=frozenset(i for i, lm in zip(ids, lms) if not lm.valid),
            names=("landmarks", "filtered landmarks (walls, floors...)", "reference frames"),
            summary=f"{len(ids)} landmarks ({len(self.valid_ids())} valid), {len(rfs)} reference frames, "
            f"{sum(counts)} points",
        )

    # ---------------------------------------------------------------------------------------- save

    def save(self, map_dir: Path | str) -> None:
        """Write ``arrays.npz`` + ``meta.json``, then ``manifest.json`` (checksums) last."""
        map_dir = Path(map_dir)
        ids = sorted(self.landmarks)
        lms = [self.landmarks[i] for i in ids]
        counts = np.array([len(lm.points) for lm in lms], dtype=np.int64)
        box_min = np.array([lm.box_min for lm in lms], dtype=np.float32).reshape(-1, 3)
        box_max = np.array([lm.box_max for lm in lms], dtype=np.float32).reshape(-1, 3)
        quantum = np.maximum(_POINT_QUANTUM_M, (box_max - box_min).max(axis=1, initial=0) / 65535.0)
        quantum = quantum.astype(np.float32)
        q_points = [
            np.clip(np.round((lm.points - box_min[k]) / quantum[k]), 0, 65535).astype(np.uint16).reshape(-1, 3)
            for k, lm in enumerate(lms)
        ]
        rfs = self.reference_frames
        rf_counts = np.array([len(rf.boxes) for rf in rfs], dtype=np.int64)
        rf_ids = [np.array(sorted(rf.boxes), dtype=np.int32) for rf in rfs]
        edges = sorted(
            (min(a, b), max(a, b), EDGE_KINDS.index(d.get("kind", "knn"))) for a, b, d in self.graph.edges(data=True)
        )
        arrays = {
            "landmark_ids": np.array(ids, dtype=np.int32),
            "point_counts": counts,
            "points_q": np.concatenate(q_points) if q_points else np.zeros((0, 3), np.uint16),
            "point_quantum": quantum,
            "box_min": box_min,
            "box_max": box_max,
            "center": np.array([lm.center for lm in lms], dtype=np.float32).reshape(-1, 3),
            "descriptors": (np.stack([lm.descriptor for lm in lms]) if lms else np.zeros((0, 0))).astype(np.float16),
            "rf_index": np.array([rf.index for rf in rfs], dtype=np.int32),
            "rf_T_wc": np.array([rf.T_wc for rf in rfs], dtype=np.float64).reshape(-1, 4, 4),
            "rf_counts": rf_counts,
            "rf_ids": np.concatenate(rf_ids) if rf_ids else np.zeros(0, np.int32),
            "rf_boxes": np.array([rf.boxes[i] for rf, ri in zip(rfs, rf_ids) for i in ri], dtype=np.float32).reshape(
                -1, 4
            ),
            "rf_visibility": np.array(
                [rf.visibility.get(int(i), 0.0) for rf, ri in zip(rfs, rf_ids) for i in ri], dtype=np.float16
            ),
            "graph_edges": np.array([e[:2] for e in edges], dtype=np.int32).reshape(-1, 2),
            "graph_edge_kind": np.array([e[2] for e in edges], dtype=np.uint8),
            "anchor_xyz": self.anchors.xyz.astype(np.float32),
            "anchor_codes": self.anchors.codes.astype(np.uint8),
            "anchor_landmark": self.anchors.landmark.astype(np.int32),
            "anchor_centroids": self.anchors.codec.centroids.astype(np.float32),
        }
        meta = {
            "K": np.asarray(self.K, dtype=float).tolist(),
            "width": int(self.width),
            "height": int(self.height),
            "up": np.asarray(self.up, dtype=float).tolist(),
            "encoder": self.encoder,
            "config": self.config,
            "stats": _plain({**self.stats, "bytes": component_bytes(arrays)}),
            "graph_nodes": sorted(int(n) for n in self.graph.nodes),
            "landmarks": {
                str(lm.id): {"valid": bool(lm.valid), "category": lm.category, "n_views": int(lm.n_views)} for lm in lms
            },
        }
        mapfile.write_arrays(map_dir, MAP_FORMAT_NAME, MAP_FORMAT_VERSION, arrays, meta)

    # ---------------------------------------------------------------------------------------- load

    @classmethod
    def load(cls, map_dir: Path | str) -> ObjectMap:
        """Read a map written by :meth:`save`; DataError naming the file on any inconsistency."""
        map_dir = Path(map_dir)
        a, meta = mapfile.read_arrays(map_dir, MAP_FORMAT_NAME, MAP_FORMAT_VERSION)
        try:
            return cls._from_arrays(a, meta)
        except (
            KeyError,
            ValueError,
            IndexError,
            TypeError,
            AttributeError,
        ) as e:  # arrays or meta.json of a forged map
            raise DataError(map_dir, f"malformed map arrays or metadata ({type(e).__name__}: {e})") from None

    @classmethod
    def _from_arrays(cls, a: dict[str, np.ndarray], meta: dict[str, Any]) -> ObjectMap:
        ids = [int(i) for i in a["landmark_ids"]]
        offsets = np.concatenate([[0], np.cumsum(a["point_counts"])])
        landmarks = {}
        for k, lid in enumerate(ids):
            scalars = meta["landmarks"][str(lid)]
            q = a["points_q"][offsets[k] : offsets[k + 1]].astype(np.float32)
            landmarks[lid] = Landmark(
                id=lid,
                points=(q * a["point_quantum"][k] + a["box_min"][k]).astype(np.float32),
                box_min=a["box_min"][k].astype(np.float64),
                box_max=a["box_max"][k].astype(np.float64),
                center=a["center"][k].astype(np.float64),
                descriptor=a["descriptors"][k].astype(np.float32),
                valid=bool(scalars["valid"]),
                category=scalars["category"],
                n_views=int(scalars["n_views"]),
            )
        rf_off = np.concatenate([[0], np.cumsum(a["rf_counts"])])
        rfs = []
        for k in range(len(a["rf_index"])):
            sl = slice(rf_off[k], rf_off[k + 1])
            rids = [int(i) for i in a["rf_ids"][sl]]
            rfs.append(
                ReferenceFrame(
                    index=int(a["rf_index"][k]),
                    T_wc=a["rf_T_wc"][k].copy(),
                    boxes={i: b.copy() for i, b in zip(rids, a["rf_boxes"][sl])},
                    visibility={i: float(v) for i, v in zip(rids, a["rf_visibility"][sl])},
                )
            )
        codec = DescriptorCodec(a["anchor_centroids"])
        parts, levels, width = codec.centroids.shape
        xyz = a["anchor_xyz"].reshape(-1, 3)
        anchors = Anchors(xyz, a["anchor_codes"].reshape(len(xyz), parts), a["anchor_landmark"].ravel(), codec)
        if not len(anchors.xyz) == len(anchors.codes) == len(anchors.landmark) or (
            parts and (levels != 256 or parts * width != DESCRIPTOR_SIZE)
        ):
            raise ValueError("anchor arrays of different lengths or a malformed codebook")
        graph = nx.Graph()
        graph.add_nodes_from(int(n) for n in meta["graph_nodes"])
        for (u, v), kind in zip(a["graph_edges"], a["graph_edge_kind"]):
            graph.add_edge(int(u), int(v), kind=EDGE_KINDS[int(kind)])
        return cls(
            landmarks=landmarks,
            reference_frames=rfs,
            graph=graph,
            K=np.asarray(meta["K"], dtype=np.float64),
            width=int(meta["width"]),
            height=int(meta["height"]),
            encoder=meta["encoder"],
            config=meta["config"],
            stats=meta["stats"],
            anchors=anchors,
            up=np.asarray(meta["up"], dtype=np.float64).reshape(3),
        )


def map_size_bytes(map_dir: Path | str) -> int:
    """Bytes of every file of a saved map (what the harness counts as map size)."""
    return sum(p.stat().st_size for p in Path(map_dir).rglob("*") if p.is_file())


COMPONENTS = {
    "landmarks": ("landmark_ids", "point_counts", "points_q", "point_quantum", "box_min", "box_max", "center"),
    "descriptors": ("descriptors",),
    "reference_frames": ("rf_index", "rf_T_wc", "rf_counts", "rf_ids", "rf_boxes", "rf_visibility"),
    "scene_graph": ("graph_edges", "graph_edge_kind"),
    "anchors": (
        "anchor_xyz",
        "anchor_codes",
        "anchor_landmark",
        "anchor_centroids",
    ),
}
"""The map's parts, by the arrays that hold them."""


def component_bytes(arrays: dict[str, np.ndarray]) -> dict[str, int]:
    """Uncompressed bytes of each of :data:`COMPONENTS` (the map's files add metadata and compression)."""
    return {part: int(sum(arrays[k].nbytes for k in keys)) for part, keys in COMPONENTS.items()}


def _plain(v: Any) -> Any:
    """JSON-safe copy of stats (numpy scalars/arrays, tuples, int keys)."""
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, Path):
        return str(v)
    return v
