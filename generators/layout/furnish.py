"""Furnishing: assets from the scene's :class:`~generators.asset_packs.AssetLibrary` placed in each room.

Objects come by room kind and placement: floor furniture against walls or free, items on the surfaces of
tables and shelves, wall-mounted items and ceiling lights. Any two instances' world boxes are disjoint
(except an item and its support), which rules out interpenetration conservatively, and every room stays
walkable (:func:`~generators.layout.free_space.free_space`). Identical copies reuse one
:class:`~generators.assets.Asset` (chair sets around tables, twin items); near-duplicates force the first
copy's colour, material and size.
"""

from __future__ import annotations

import math

import numpy as np
import trimesh
from scipy import ndimage

from generators.asset_packs import library_for
from generators.assets import Asset
from generators.layout.free_space import GRID_RES, free_space
from generators.layout.model import DOOR_H, DOOR_W, Instance, LayoutDraft, Room

MIN_FREE_SHARE = 0.3
"""Furnishing keeps at least this share of a room's walkable area free (room for camera paths)."""


def _yaw_pose(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    T = trimesh.transformations.rotation_matrix(yaw, (0, 0, 1))
    T[:3, 3] = (x, y, z)
    return T


def _boxes_overlap(a: np.ndarray, b: np.ndarray, eps: float = 1e-4) -> bool:
    return bool(np.all(a[0] < b[1] - eps) and np.all(b[0] < a[1] - eps))


class _Boxes:
    """Growing set of (instance id, world box) with a vectorised overlap query."""

    def __init__(self, items: list[tuple[int, np.ndarray]]):
        self.ids = [i for i, _ in items]
        self.boxes = np.array([b for _, b in items]).reshape(-1, 2, 3)

    def append(self, item: tuple[int, np.ndarray]) -> None:
        self.ids.append(item[0])
        self.boxes = np.concatenate([self.boxes, item[1][None]])

    def hits(self, box: np.ndarray, ignore: set[int], eps: float = 1e-4) -> bool:
        m = np.all(box[0] < self.boxes[:, 1] - eps, axis=1) & np.all(self.boxes[:, 0] < box[1] - eps, axis=1)
        return any(self.ids[k] not in ignore for k in np.flatnonzero(m))


class Furnisher:
    """Places the assets of a :class:`LayoutDraft`'s rooms, drawing from its random stream."""

    def __init__(self, draft: LayoutDraft):
        self.draft = draft
        self.rng = draft.rng
        self.library = library_for(draft.spec)
        self._empty_free: dict[str, int] = {}

    def _occupied(self, room: Room) -> _Boxes:
        """Boxes furniture must avoid: this room's stairs and railings (door frames and windows are kept
        clear by the door and window zones; objects are added as they are placed)."""
        return _Boxes(
            [
                (i.id, i.aabb)
                for i in self.draft.instances
                if i.room == room.name and i.category not in ("wall", "floor", "ceiling", "window", "door")
            ]
        )

    def _fits(self, box: np.ndarray, room: Room, ignore: set[int], occupied: _Boxes) -> bool:
        x0, y0, x1, y1 = room.rect
        if box[0, 0] < x0 - 1e-6 or box[0, 1] < y0 - 1e-6 or box[1, 0] > x1 + 1e-6 or box[1, 1] > y1 + 1e-6:
            return False
        if box[1, 2] > room.z0 + room.height + 1e-6:
            return False
        return not occupied.hits(box, ignore)

    def _walkable(self, room: Room, occupied: _Boxes, box: np.ndarray) -> bool:
        """Would the room stay walkable with ``box`` added: one connected free region that reaches every
        doorway and keeps MIN_FREE_SHARE of the empty room's free area?"""
        x0, y0, x1, y1 = room.rect
        xs, ys = np.meshgrid(
            np.arange(x0 - 0.4, x1 + 0.4, GRID_RES) + GRID_RES / 2,
            np.arange(y0 - 0.4, y1 + 0.4, GRID_RES) + GRID_RES / 2,
        )
        doors = [d for d in self.draft.doors if room.name in d.rooms]
        blocked = [rect for f, rect in self.draft.blocked if f == room.floor]
        inside = (xs >= x0) & (xs <= x1) & (ys >= y0) & (ys <= y1)
        if room.name not in self._empty_free:
            self._empty_free[room.name] = (
                free_space(xs, ys, [room], doors, np.zeros((0, 2, 3)), blocked, room.z0) & inside
            ).sum()
        free = free_space(xs, ys, [room], doors, np.concatenate([occupied.boxes, box[None]]), blocked, room.z0)
        if (free & inside).sum() < MIN_FREE_SHARE * self._empty_free[room.name]:
            return False
        # passages must be wider than one cell: this grid is aligned to the room, the trajectories' grid to
        # the footprint, so a one-cell gap here can be closed there (measured: a pendant light in a corridor)
        passable = ndimage.binary_erosion(free, structure=np.ones((3, 3)))
        labels, n = ndimage.label(passable, structure=np.ones((3, 3)))
        if n != 1:
            return False
        for d in doors:
            near = (np.abs(xs - d.centre[0]) <= 0.2) & (np.abs(ys - d.centre[1]) <= 0.2)
            if not (passable & near).any():
                return False
        return True

    def _door_zones(self, room: Room) -> list[np.ndarray]:
        """Boxes in front of this room's doors that furniture must keep clear."""
        zones = []
        for d in self.draft.doors:
            if room.name not in d.rooms:
                continue
            cx, cy = d.centre[:2]
            half = DOOR_W / 2 + 0.15
            lo = np.array([cx - half, cy - 1.0, room.z0]) if d.axis == 0 else np.array([cx - 1.0, cy - half, room.z0])
            hi = (
                np.array([cx + half, cy + 1.0, room.z0 + DOOR_H])
                if d.axis == 0
                else np.array([cx + 1.0, cy + half, room.z0 + DOOR_H])
            )
            zones.append(np.stack([lo, hi]))
        return zones

    def _window_zones(self, room: Room) -> list[np.ndarray]:
        return [i.aabb for i in self.draft.instances if i.category == "window" and i.room == room.name]

    def _pick(self, room: Room, placement: str) -> str | None:
        cats = self.library.categories(room.kind, placement)
        if not cats:
            return None
        w = np.array([c.weight for c in cats], float)
        return cats[int(self.rng.choice(len(cats), p=w / w.sum()))].name

    def _place_instance(self, asset: Asset, room: Room, T: np.ndarray, support: int | None = None) -> Instance:
        return self.draft.add(
            category=asset.category,
            parts=asset.parts,
            transform=T,
            structural=False,
            room=room.name,
            floor=room.floor,
            description=asset.description,
            attributes=dict(asset.attributes),
            placement=asset.placement,
            support=support,
            surface_heights=list(asset.surface_heights),
        )

    @staticmethod
    def _corners(asset: Asset) -> np.ndarray:
        """(8,3) corners of an asset's local box (computed once per placement attempt)."""
        lo = np.min([p.mesh.bounds[0] for p in asset.parts], axis=0)
        hi = np.max([p.mesh.bounds[1] for p in asset.parts], axis=0)
        return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])

    @staticmethod
    def _aabb_at(corners: np.ndarray, T: np.ndarray) -> np.ndarray:
        """World box of local box corners under transform T (conservative for rotated objects)."""
        pts = corners @ T[:3, :3].T + T[:3, 3]
        return np.stack([pts.min(axis=0), pts.max(axis=0)])

    def _try_floor(
        self, asset: Asset, room: Room, occupied: _Boxes, keep_clear: list, tries: int = 30
    ) -> Instance | None:
        rng = self.rng
        x0, y0, x1, y1 = room.rect
        ext = asset.extent
        corners = self._corners(asset)
        for _ in range(tries):
            if asset.placement in ("wall", "wall_mounted"):
                side = int(rng.integers(4))
                normal = [(0, 1), (-1, 0), (0, -1), (1, 0)][side]  # inward normals of walls y0, x1, y1, x0
                yaw = math.atan2(normal[1], normal[0]) - math.pi / 2
                along = rng.uniform(0, 1)
                back = ext[1] / 2 + 0.01
                if side == 0:
                    x, y = x0 + ext[0] / 2 + along * (x1 - x0 - ext[0]), y0 + back
                elif side == 1:
                    x, y = x1 - back, y0 + ext[0] / 2 + along * (y1 - y0 - ext[0])
                elif side == 2:
                    x, y = x0 + ext[0] / 2 + along * (x1 - x0 - ext[0]), y1 - back
                else:
                    x, y = x0 + back, y0 + ext[0] / 2 + along * (y1 - y0 - ext[0])
                z = room.z0 + (rng.uniform(1.2, 1.9) - ext[2] / 2 if asset.placement == "wall_mounted" else 0.0)
            elif asset.placement == "ceiling":
                x, y = (
                    rng.uniform(x0 + ext[0] / 2, max(x1 - ext[0] / 2, x0 + ext[0] / 2)),
                    rng.uniform(y0 + ext[1] / 2, max(y1 - ext[1] / 2, y0 + ext[1] / 2)),
                )
                yaw, z = float(rng.integers(4)) * math.pi / 2, room.z0 + room.height - ext[2]
            else:
                x, y = rng.uniform(x0, x1), rng.uniform(y0, y1)
                yaw, z = rng.uniform(0, 2 * math.pi), room.z0
            T = _yaw_pose(x, y, z, yaw)
            box = self._aabb_at(corners, T)
            if not self._fits(box, room, set(), occupied):
                continue
            if asset.placement != "ceiling" and any(_boxes_overlap(box, zb) for zb in keep_clear):
                continue
            if not self._walkable(room, occupied, box):
                continue
            inst = self._place_instance(asset, room, T)
            occupied.append((inst.id, box))
            return inst
        return None

    def _try_surface(
        self, asset: Asset, room: Room, supports: list[Instance], occupied: _Boxes, tries: int = 20
    ) -> Instance | None:
        rng = self.rng
        ext = asset.extent
        corners = self._corners(asset)
        for _ in range(tries):
            sup = supports[int(rng.integers(len(supports)))]
            hs = sup.surface_heights
            k = int(rng.integers(len(hs)))
            gap = (hs[k + 1] - hs[k] - 0.03) if k + 1 < len(hs) else np.inf
            if ext[2] > gap:
                continue
            lb = sup.local_bounds
            if ext[0] > lb[1, 0] - lb[0, 0] - 0.04 or ext[1] > lb[1, 1] - lb[0, 1] - 0.04:
                continue
            lx = rng.uniform(lb[0, 0] + ext[0] / 2 + 0.02, lb[1, 0] - ext[0] / 2 - 0.02)
            ly = rng.uniform(lb[0, 1] + ext[1] / 2 + 0.02, lb[1, 1] - ext[1] / 2 - 0.02)
            yaw_local = float(rng.choice([0.0, rng.uniform(-0.4, 0.4)]))
            T = sup.transform @ _yaw_pose(lx, ly, hs[k] + 1e-3, yaw_local)
            box = self._aabb_at(corners, T)
            if not self._fits(box, room, {sup.id}, occupied):
                continue
            inst = self._place_instance(asset, room, T, support=sup.id)
            occupied.append((inst.id, box))
            return inst
        return None

    def _chairs_around(self, table: Instance, room: Room, occupied: _Boxes, keep_clear: list) -> list[Instance]:
        """An identical chair set around a table (one Asset reused)."""
        chair_cats = [c.name for c in self.library.categories(room.kind, "floor") if "chair" in c.name]
        if not chair_cats:
            return []
        chair = self.library.sample(chair_cats[int(self.rng.integers(len(chair_cats)))], self.rng)
        lb = table.local_bounds
        ce = chair.extent
        chair_corners = self._corners(chair)
        spots = []
        for sx in (-1, 1):  # along the table's long sides (local x) facing the table
            for t in (0.0,) if lb[1, 0] - lb[0, 0] < 1.2 else (-0.3, 0.3):
                u = t * (lb[1, 0] - lb[0, 0])
                spots.append((u, sx * ((lb[1, 1] - lb[0, 1]) / 2 + ce[1] / 2 + 0.05), math.pi if sx > 0 else 0.0))
        placed = []
        for lx, ly, yaw in spots:
            T = table.transform @ _yaw_pose(lx, ly, 0.0, yaw)
            box = self._aabb_at(chair_corners, T)
            if (
                self._fits(box, room, set(), occupied)
                and not any(_boxes_overlap(box, z) for z in keep_clear)
                and self._walkable(room, occupied, box)
            ):
                inst = self._place_instance(chair, room, T)
                occupied.append((inst.id, box))
                placed.append(inst)
        return placed

    def furnish(self, room: Room) -> None:
        """Place up to ``objects_per_room`` assets in ``room``: a ceiling fitting at each light, then floor
        furniture (chair sets around tables), wall-mounted items and items on surfaces."""
        rng = self.rng
        target = self.draft.spec.objects_per_room
        if target == 0:
            return
        occupied = self._occupied(room)
        keep_clear = self._door_zones(room) + self._window_zones(room)
        placed: list[Instance] = []
        previous: dict[str, Asset] = {}

        def sample(cat: str) -> Asset:
            """Identical copy (30%), near-duplicate (15%) or a fresh asset."""
            u = rng.random()
            if cat in previous and u < 0.30:
                return previous[cat]
            if cat in previous and u < 0.45:
                return self.library.sample(cat, rng, like=previous[cat])
            previous[cat] = self.library.sample(cat, rng)
            return previous[cat]

        # ceiling lights first (one per light), then furniture, wall items, surface items
        for light in [li for li in self.draft.lights if li.room == room.name]:
            cat = self._pick(room, "ceiling")
            if cat is None or len(placed) >= target:
                break
            asset = previous.get(cat) or sample(cat)
            T = _yaw_pose(light.pos[0], light.pos[1], room.z0 + room.height - asset.extent[2], 0.0)
            box = self._aabb_at(self._corners(asset), T)
            # a pendant hanging below CAMERA_TOP obstructs cameras: in a corridor it can cut the floor in two
            if self._fits(box, room, set(), occupied) and self._walkable(room, occupied, box):
                inst = self._place_instance(asset, room, T)
                occupied.append((inst.id, box))
                placed.append(inst)
        n_floor = max(1, int(round(0.45 * target)))
        n_wall = max(0, int(round(0.15 * target)))
        misses = 0
        while (
            sum(1 for p in placed if p.placement in ("floor", "wall")) < n_floor
            and len(placed) < target
            and misses < 3 * target + 10
        ):
            cat = self._pick(room, "wall" if rng.random() < 0.6 else "floor")
            if cat is None:
                misses += 1
                continue
            inst = self._try_floor(sample(cat), room, occupied, keep_clear)
            if inst is None:
                misses += 1
                continue
            placed.append(inst)
            if inst.surface_heights and "table" in inst.category and rng.random() < 0.7 and len(placed) < target:
                placed += self._chairs_around(inst, room, occupied, keep_clear)[: target - len(placed)]
        misses = 0
        while (
            sum(1 for p in placed if p.placement == "wall_mounted") < n_wall
            and len(placed) < target
            and misses < 2 * n_wall + 5
        ):
            cat = self._pick(room, "wall_mounted")
            inst = self._try_floor(sample(cat), room, occupied, keep_clear) if cat else None
            if inst is None:
                misses += 1
                continue
            placed.append(inst)
        misses = 0
        while len(placed) < target and misses < 3 * target + 10:
            supports = [p for p in placed if p.surface_heights]
            if supports and rng.random() < 0.85:
                cat = self._pick(room, "surface")
                inst = self._try_surface(sample(cat), room, supports, occupied) if cat else None
            else:
                cat = self._pick(room, "wall" if rng.random() < 0.5 else "floor")
                inst = self._try_floor(sample(cat), room, occupied, keep_clear) if cat else None
            if inst is None:
                misses += 1
                continue
            placed.append(inst)
