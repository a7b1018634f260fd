"""Query-split variants: progressive illumination decay and displaced objects (same query poses).

``query_light1..4`` follow the paper's four levels of decay: each is dimmer than the last
(``SceneSpec.light_levels``), the colour drifts warm / cool, and the last two switch a growing share
of the room lights off. ``query_displaced`` moves or rotates ``n_displaced`` objects (human-style
rearrangement); the mapping split is never affected, and every move is recorded in
``query_displaced/displacements.json``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from generators.layout import Instance, Layout
from generators.spec import SceneSpec

LIGHT_SPLITS = ("query_light1", "query_light2", "query_light3", "query_light4")
_TINTS = ((1.0, 0.97, 0.92), (1.0, 0.86, 0.70), (0.78, 0.86, 1.0), (1.0, 0.72, 0.52))
_OFF_SHARE = (0.0, 0.0, 0.25, 0.5)


@dataclass
class Lighting:
    """Arguments of :meth:`generators.render.Renderer.set_lighting` for one split."""

    level: float = 1.0
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)
    lights_off: tuple[int, ...] = ()


def light_variants(spec: SceneSpec, n_lights: int) -> dict[str, Lighting]:
    """Lighting of each query_light split (deterministic in the seed)."""
    rng = np.random.default_rng([spec.seed, 17])
    order = rng.permutation(n_lights)
    out = {}
    for k, split in enumerate(LIGHT_SPLITS):
        n_off = min(int(math.floor(_OFF_SHARE[k] * n_lights)), max(n_lights - 1, 0))
        out[split] = Lighting(float(spec.light_levels[k]), _TINTS[k], tuple(sorted(int(i) for i in order[:n_off])))
    return out


@dataclass
class Displacement:
    """One moved object (recorded in displacements.json)."""

    id: int
    category: str
    room: str | None
    kind: str
    """'moved', 'rotated' or 'moved+rotated'."""
    translation: list[float]
    """World translation of the object's base (m)."""
    yaw_deg: float
    """Rotation about the object's vertical axis (deg)."""
    transform_before: list[list[float]]
    transform_after: list[list[float]]
    aabb_before: list[list[float]]
    aabb_after: list[list[float]]


def _overlap(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.all(a[0] < b[1] - 1e-4) and np.all(b[0] < a[1] - 1e-4))


def _aabb(inst: Instance, T: np.ndarray) -> np.ndarray:
    pts = np.concatenate([p.mesh.vertices for p in inst.parts]) @ T[:3, :3].T + T[:3, 3]
    return np.stack([pts.min(axis=0), pts.max(axis=0)])


def sample_displacements(layout: Layout, spec: SceneSpec, keep_free: np.ndarray, tries: int = 60) -> list[Displacement]:
    """Move / rotate up to ``spec.n_displaced`` objects without collisions or enclosing a query camera.

    Candidates are floor, wall-backed and surface objects that support nothing; surface items stay on
    their support, wall-backed ones slide along their wall.
    """
    rng = np.random.default_rng([spec.seed, 19])
    rooms = {r.name: r for r in layout.rooms}
    supported = {i.support for i in layout.instances if i.support is not None}
    candidates = [
        i
        for i in layout.instances
        if not i.structural and i.placement in ("floor", "wall", "surface") and i.id not in supported
    ]
    boxes = {i.id: i.aabb for i in layout.instances if i.category not in ("wall", "floor", "ceiling", "window")}
    out: list[Displacement] = []
    for idx in rng.permutation(len(candidates)):
        if len(out) >= spec.n_displaced:
            break
        inst = candidates[int(idx)]
        room = rooms[inst.room]
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
            x0, y0, x1, y1 = room.rect
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
            boxes[inst.id] = box
            out.append(
                Displacement(
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
            )
            break
    return out
