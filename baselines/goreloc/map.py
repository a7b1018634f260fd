"""GOReloc's map: ellipsoids with COCO label counts, the object graph, and the mapping camera.

Everything the query side needs and nothing else (GOReloc's own map also keeps ORB-SLAM2 keyframes
and map points, which its relocalisation does not use). On disk, a versioned, checksummed file set
(:mod:`openreloc_bench.data.mapfile`)::

    arrays.npz      object ids, ellipsoids (centre, rotation, semi-axes), label counts (N x 80),
                    graph edges, and the dataset instance id -> COCO label table
    meta.json       format version, camera, labelling encoder, mapping config, stats, categories
    manifest.json   written last: format name + version and the sha256 and size of each file
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from baselines.goreloc.vocabulary import COCO_CLASSES, N_CLASSES
from openreloc_bench.data import mapfile
from openreloc_bench.errors import DataError
from openreloc_bench.methods import MapPoints

FORMAT_NAME = "goreloc-map"
FORMAT_VERSION = 1


@dataclass
class GORelocMap:
    """The map; :meth:`save` / :meth:`load` give its file set."""

    ids: np.ndarray
    """(N,) object ids (dataset instance ids with oracle masks, cluster ids with a segmenter)."""
    centres: np.ndarray
    """(N, 3) ellipsoid centres (world, m)."""
    rotations: np.ndarray
    """(N, 3, 3) ellipsoid axes as columns."""
    axes: np.ndarray
    """(N, 3) semi-axis lengths (m)."""
    label_counts: np.ndarray
    """(N, 80) how often each object was detected with each COCO label while mapping."""
    edges: np.ndarray
    """(E, 2) object-graph edges as index pairs (i < j) into the objects."""
    instance_labels: dict[int, int]
    """Dataset instance id -> COCO label (the oracle-mask track's detector); empty without categories."""
    K: np.ndarray
    """(3, 3) intrinsics of the mapping camera."""
    width: int
    height: int
    encoder: dict[str, Any] | None
    """The encoder that labelled the mapping masks (config + weights fingerprint), None for oracle labels."""
    categories: list[str | None]
    """Per object, its dataset category when known (diagnostics only, never used to localize)."""
    config: dict[str, Any]
    """Mapping config as plain data."""
    stats: dict[str, Any]
    """Counts and timings of the mapping run."""

    @property
    def labels(self) -> np.ndarray:
        """(N,) each object's dominant COCO label."""
        return self.label_counts.argmax(axis=1) if len(self.ids) else np.zeros(0, np.int64)

    def adjacency(self) -> np.ndarray:
        """(N, N) symmetric bool object graph."""
        adj = np.zeros((len(self.ids), len(self.ids)), bool)
        adj[self.edges[:, 0], self.edges[:, 1]] = True
        return adj | adj.T

    def drawn(self, per_object: int = 200) -> MapPoints:
        """Each object's ellipsoid as ``per_object`` points on its surface (a Fibonacci sphere, scaled and
        turned), labelled with its most frequent COCO label."""
        k = np.arange(per_object) + 0.5
        z, phi = 1 - 2 * k / per_object, np.pi * (1 + 5**0.5) * k
        sphere = np.c_[np.sqrt(1 - z**2) * np.cos(phi), np.sqrt(1 - z**2) * np.sin(phi), z]
        shells = [c + (sphere * a) @ R.T for c, R, a in zip(self.centres, self.rotations, self.axes)]
        labels = {
            int(i): f"object {i}: {COCO_CLASSES[int(np.argmax(n))]} ({cat or 'no category'}), "
            f"semi-axes {a[0]:.2f} x {a[1]:.2f} x {a[2]:.2f} m"
            for i, n, cat, a in zip(self.ids, self.label_counts, self.categories, self.axes)
        }
        return MapPoints(
            points=np.concatenate(shells) if shells else np.zeros((0, 3)),
            group=np.repeat(self.ids.astype(np.int64), per_object),
            labels=labels,
            K=self.K,
            size=(self.width, self.height),
            names=("objects (ellipsoids)", "", "cameras"),
            summary=f"{len(self.ids)} objects (ellipsoids), {len(self.edges)} graph edges",
        )

    def save(self, map_dir: Path | str) -> None:
        inst = sorted(self.instance_labels.items())
        arrays = {
            "ids": np.asarray(self.ids, np.int64),
            "centres": np.asarray(self.centres, np.float64).reshape(-1, 3),
            "rotations": np.asarray(self.rotations, np.float64).reshape(-1, 3, 3),
            "axes": np.asarray(self.axes, np.float64).reshape(-1, 3),
            "label_counts": np.asarray(self.label_counts, np.int32).reshape(-1, N_CLASSES),
            "edges": np.asarray(self.edges, np.int64).reshape(-1, 2),
            "instance_ids": np.array([i for i, _ in inst], np.int64),
            "instance_labels": np.array([lab for _, lab in inst], np.int64),
        }
        meta = {
            "K": np.asarray(self.K, np.float64).tolist(),
            "width": int(self.width),
            "height": int(self.height),
            "encoder": self.encoder,
            "categories": self.categories,
            "config": self.config,
            "stats": self.stats,
        }
        Path(map_dir).mkdir(parents=True, exist_ok=True)
        mapfile.write_arrays(map_dir, FORMAT_NAME, FORMAT_VERSION, arrays, meta)

    @classmethod
    def load(cls, map_dir: Path | str) -> GORelocMap:
        """Read a map written by :meth:`save`; a DataError naming the file on any inconsistency."""
        map_dir = Path(map_dir)
        a, meta = mapfile.read_arrays(map_dir, FORMAT_NAME, FORMAT_VERSION)
        try:
            m = cls(
                ids=a["ids"],
                centres=a["centres"],
                rotations=a["rotations"],
                axes=a["axes"],
                label_counts=a["label_counts"].astype(np.int64),
                edges=a["edges"],
                instance_labels={int(i): int(lab) for i, lab in zip(a["instance_ids"], a["instance_labels"])},
                K=np.asarray(meta["K"], np.float64),
                width=int(meta["width"]),
                height=int(meta["height"]),
                encoder=meta["encoder"],
                categories=list(meta["categories"]),
                config=meta["config"],
                stats=meta["stats"],
            )
        except (KeyError, TypeError, ValueError) as e:
            raise DataError(map_dir / mapfile.ARRAYS, f"malformed map ({type(e).__name__}: {e})") from None
        n = len(m.ids)
        shapes_ok = (
            m.centres.shape == (n, 3)
            and m.rotations.shape == (n, 3, 3)
            and m.axes.shape == (n, 3)
            and m.label_counts.shape == (n, N_CLASSES)
            and len(m.categories) == n
            and m.edges.ndim == 2
            and m.edges.shape[1] == 2
            and (m.edges.size == 0 or (m.edges.min() >= 0 and m.edges.max() < n))
        )
        if not shapes_ok:
            raise DataError(map_dir / mapfile.ARRAYS, "malformed map (array shapes do not agree)")
        return m
