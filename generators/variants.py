"""Query-split variants: progressive illumination decay and displaced objects (same query poses).

Each query split is lit as its row of :data:`~openreloc_bench.data.splits.QUERY_SPLIT_TABLE` says: the
lighting variants dimmer (``SceneSpec.light_levels``), tinted, with a share of the room lights off and,
in the dark ones, the camera-mounted light too, as a hand-held camera has none.
``query_displaced`` moves, rotates, removes and adds a share of each room's objects, drawn among those
the queries see (human-style rearrangement); the mapping split is never affected, and every change is
recorded in ``query_displaced/displacements.json``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from generators.layout import Instance, Layout
from generators.spec import SceneSpec
from openreloc_bench.data.splits import LIGHT, QUERY_SPLIT_TABLE, split_names


@dataclass
class Lighting:
    """Arguments of :meth:`generators.render.Renderer.set_lighting` for one split."""

    level: float = 1.0
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)
    lights_off: tuple[int, ...] = ()
    headlight: bool = True
    """The light along the camera's axis (off in the dark splits: darkness is not a dimmer)."""


def query_lighting(spec: SceneSpec, n_lights: int) -> dict[str, Lighting]:
    """Lighting of every query split, as its row of the split table says, at the level the spec gives each
    lighting variant; the lights switched off are drawn once (deterministic in the seed), each split
    switching off the first of them."""
    rng = np.random.default_rng([spec.seed, 17])
    order = rng.permutation(n_lights)
    levels = dict(zip(split_names(LIGHT), spec.light_levels))
    out = {}
    for split in QUERY_SPLIT_TABLE:
        n_off = min(int(math.floor(split.lights_off * n_lights)), max(n_lights - 1, 0))
        off = tuple(sorted(int(i) for i in order[:n_off]))
        out[split.name] = Lighting(float(levels.get(split.name, split.level)), split.tint, off, split.headlight)
    return out


CHANGE_KINDS = ("moved", "rotated", "moved+rotated", "removed", "added")
HIDDEN_Z_M = -1000.0
"""Where an object not in a split is put: far below every floor, out of every view."""


@dataclass
class Displacement:
    """One changed object between mapping and ``query_displaced`` (recorded in displacements.json)."""

    id: int
    category: str
    room: str | None
    kind: str
    """One of :data:`CHANGE_KINDS`: moved and / or rotated in place; 'removed' (gone from
    ``query_displaced``); 'added' (absent from every other split)."""
    translation: list[float]
    """World translation of the object's base (m); zero for removed and added objects."""
    yaw_deg: float
    """Rotation about the object's vertical axis (deg)."""
    transform_before: list[list[float]]
    """Where it stands in the mapping split (for 'added': where it appears in ``query_displaced``)."""
    transform_after: list[list[float]]
    aabb_before: list[list[float]]
    aabb_after: list[list[float]]

    @property
    def shown_in_mapping(self) -> bool:
        return self.kind != "added"

    @property
    def shown_displaced(self) -> bool:
        return self.kind != "removed"


def hidden(T: np.ndarray) -> np.ndarray:
    """``T`` moved out of sight (how a renderer drops an object from a split)."""
    out = np.array(T, dtype=np.float64)
    out[2, 3] += HIDDEN_Z_M
    return out


def _overlap(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.all(a[0] < b[1] - 1e-4) and np.all(b[0] < a[1] - 1e-4))


def _aabb(inst: Instance, T: np.ndarray) -> np.ndarray:
    pts = np.concatenate([p.mesh.vertices for p in inst.parts]) @ T[:3, :3].T + T[:3, 3]
    return np.stack([pts.min(axis=0), pts.max(axis=0)])


def _seen_first(ids: list[int], seen: Mapping[int, int], rng: np.random.Generator) -> list[int]:
    """``ids`` in a random order drawn by how many queries see each (weighted sampling without
    replacement, Gumbel keys); objects no query sees follow, shuffled."""
    keys = [np.log(seen[i]) + rng.gumbel() if seen.get(i, 0) > 0 else -np.inf for i in ids]
    tiebreak = rng.permutation(len(ids))
    return [ids[k] for k in sorted(range(len(ids)), key=lambda k: (-keys[k], tiebreak[k]))]


def sample_displacements(
    layout: Layout, spec: SceneSpec, keep_free: np.ndarray, seen: Mapping[int, int], tries: int = 60
) -> list[Displacement]:
    """The changes of ``query_displaced``, room by room: ``spec.displaced_share`` of a room's objects
    moved or rotated, ``removed_share`` removed and ``added_share`` added, each drawn among the objects
    the queries see (``seen``: queries per object id), so that the change is in view.

    Candidates are floor, wall-backed and surface objects that support nothing; moves avoid collisions
    and query cameras (``keep_free``), surface items stay on their support, wall-backed ones slide along
    their wall. Deterministic in the seed.
    """
    rng = np.random.default_rng([spec.seed, 19])
    supported = {i.support for i in layout.instances if i.support is not None}
    boxes = {i.id: i.aabb for i in layout.instances if i.category not in ("wall", "floor", "ceiling", "window")}
    out: list[Displacement] = []
    for room in layout.rooms:
        objects = [i for i in layout.instances if i.room == room.name and not i.structural]
        candidates = [i for i in objects if i.placement in ("floor", "wall", "surface") and i.id not in supported]
        by_id = {i.id: i for i in candidates}
        order = _seen_first([i.id for i in candidates], seen, rng)
        n_moved, n_removed, n_added = (
            int(round(share * len(objects))) for share in (spec.displaced_share, spec.removed_share, spec.added_share)
        )
        for kind, n in (("removed", n_removed), ("added", n_added)):
            for i in order[:n]:
                T = np.round(by_id[i].transform, 9).tolist()
                box = np.round(by_id[i].aabb, 5).tolist()
                out.append(Displacement(i, by_id[i].category, room.name, kind, [0.0, 0.0, 0.0], 0.0, T, T, box, box))
            order = order[n:]
        moved = 0
        for i in order:
            if moved >= n_moved:
                break
            change = _move(by_id[i], room.rect, boxes, keep_free, rng, tries)
            if change is not None:
                boxes[i] = np.asarray(change.aabb_after)
                out.append(change)
                moved += 1
    return out


def _move(
    inst: Instance,
    rect: tuple[float, float, float, float],
    boxes: dict[int, np.ndarray],
    keep_free: np.ndarray,
    rng: np.random.Generator,
    tries: int,
) -> Displacement | None:
    """A collision-free move and / or rotation of ``inst`` inside its room, or None after ``tries``."""
    for _ in range(tries):
        kind = ("moved", "rotated", "moved+rotated")[int(rng.integers(3))]
        yaw = 0.0
        if kind != "moved" and inst.placement != "wall":
            yaw = float(rng.uniform(30, 180) * rng.choice([-1, 1]))
        elif kind == "rotated":
            continue
        shift = np.zeros(3)
        if kind != "rotated":
            dist = rng.uniform(0.1, 0.4) if inst.placement == "surface" else rng.uniform(0.3, 1.2)
            if inst.placement == "wall":  # slide along the wall (the object's local x axis)
                shift = inst.transform[:3, 0] * dist * rng.choice([-1, 1])
            else:
                a = rng.uniform(0, 2 * np.pi)
                shift = np.array([np.cos(a), np.sin(a), 0.0]) * dist
        T_new = inst.transform.copy()
        T_new[:3, :3] = Rotation.from_euler("z", yaw, degrees=True).as_matrix() @ inst.transform[:3, :3]
        T_new[:3, 3] = inst.transform[:3, 3] + shift
        box = _aabb(inst, T_new)
        x0, y0, x1, y1 = rect
        if box[0, 0] < x0 or box[0, 1] < y0 or box[1, 0] > x1 or box[1, 1] > y1:
            continue
        if inst.support is not None:
            sb = boxes[inst.support]
            if box[0, 0] < sb[0, 0] or box[0, 1] < sb[0, 1] or box[1, 0] > sb[1, 0] or box[1, 1] > sb[1, 1]:
                continue
        if any(_overlap(box, b) for j, b in boxes.items() if j not in (inst.id, inst.support)):
            continue
        if len(keep_free) and np.any(np.all((keep_free > box[0] - 0.2) & (keep_free < box[1] + 0.2), axis=1)):
            continue
        return Displacement(
            inst.id,
            inst.category,
            inst.room,
            kind,
            np.round(shift, 6).tolist(),
            round(yaw, 4),
            np.round(inst.transform, 9).tolist(),
            np.round(T_new, 9).tolist(),
            np.round(inst.aabb, 5).tolist(),
            np.round(box, 5).tolist(),
        )
    return None
