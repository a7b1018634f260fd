"""Indoor layouts: rooms, walls, doors, windows, stairs and furnished objects as placed instances.

Floor plans are two strips of rooms (with a corridor between them when a floor has 5+ rooms) on a
rectangular footprint; walls sit on the cell boundaries (centred, :data:`WALL_T` thick), doorways
connect every room to the rest (a spanning tree of the adjacency graph plus a few loops), outer walls
get windows. Multi-floor scenes stack floors with the same footprint; a straight stair run stands
against an outer wall of a stair room whose x-range is the same on the two floors it joins, and the
slab above it has an opening with a railing.

Objects come from :mod:`generators.assets` by room kind and placement: floor furniture against walls
or free, items on the surfaces of tables and shelves, wall-mounted items and ceiling lights. Any two
instances' world boxes are disjoint (except an item and its support), which rules out interpenetration
conservatively. Identical copies reuse one :class:`~generators.assets.Asset` (chair sets around
tables, twin items); near-duplicates force the first copy's colour, material and size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import networkx as nx
import numpy as np
import trimesh
from scipy import ndimage

from generators.asset_packs import library_for
from generators.assets import Asset, Part
from generators.materials import COLOURS
from generators.spec import SceneSpec
from openreloc_bench.data.scene import ObjectInfo

WALL_T = 0.1
"""Wall thickness (m)."""
SLAB_T = 0.1
"""Floor and ceiling slab thickness (m)."""
STOREY_GAP = 0.3
"""Vertical distance from one floor's ceiling surface to the next floor's floor surface (m)."""
DOOR_W, DOOR_H = 0.9, 2.1
CORRIDOR_W = 1.6
STAIR_LEN, STAIR_W = 4.0, 1.0
ROOM_KINDS_NO_CORRIDOR = ("bedroom", "kitchen", "living", "office", "bathroom", "dining")
_FLOOR_MATERIAL = {
    "bedroom": "wood",
    "living": "wood",
    "office": "wood",
    "dining": "wood",
    "kitchen": "ceramic",
    "bathroom": "ceramic",
    "corridor": "stone",
}
GRID_RES = 0.1
"""Free-space grid cell size (m)."""
WALL_CLEARANCE = 0.35
"""Camera distance kept from walls (m)."""
OBJECT_CLEARANCE = 0.25
"""Camera distance kept from object footprints (m)."""
CAMERA_TOP = 2.0
"""Objects whose bottom is above floor + this never obstruct a camera (ceiling items)."""
MIN_FREE_SHARE = 0.3
"""Furnishing keeps at least this share of a room's walkable area free (room for camera paths)."""
_WALL_COLOURS = ("white", "cream", "beige", "light grey", "light blue", "pink", "light brown", "grey")
_FLOOR_COLOURS = ("light brown", "brown", "tan", "beige", "grey", "dark brown", "white", "cream")


@dataclass
class Room:
    """One room: interior rectangle (inside the walls) on one floor."""

    name: str
    kind: str
    floor: int
    rect: tuple[float, float, float, float]
    """Interior (x0, y0, x1, y1) in world metres."""
    z0: float
    """Floor surface height."""
    height: float

    @property
    def area(self) -> float:
        return (self.rect[2] - self.rect[0]) * (self.rect[3] - self.rect[1])

    @property
    def centre(self) -> np.ndarray:
        return np.array([(self.rect[0] + self.rect[2]) / 2, (self.rect[1] + self.rect[3]) / 2, self.z0])

    def contains_xy(self, p: np.ndarray, margin: float = 0.0) -> bool:
        x0, y0, x1, y1 = self.rect
        return x0 + margin <= p[0] <= x1 - margin and y0 + margin <= p[1] <= y1 - margin


@dataclass
class Light:
    """A point light below a room's ceiling."""

    pos: np.ndarray
    room: str
    floor: int
    colour: tuple[float, float, float] = (1.0, 0.97, 0.92)


@dataclass
class Door:
    """A doorway between two rooms (or an opening), centre at floor level."""

    floor: int
    centre: np.ndarray
    axis: int
    """0: the wall runs along x (door crossed along y); 1: the wall runs along y."""
    rooms: tuple[str, str]


@dataclass
class Instance:
    """One placed instance: parts in the object frame plus the object-to-world transform."""

    id: int
    category: str
    parts: list[Part]
    transform: np.ndarray
    structural: bool
    room: str | None
    floor: int
    description: str = ""
    attributes: dict[str, str] = field(default_factory=dict)
    placement: str = "structural"
    support: int | None = None
    """Id of the instance this one stands on (surface items)."""
    surface_heights: list[float] = field(default_factory=list)
    local_bounds: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))

    def __post_init__(self) -> None:
        self.local_bounds = np.array(
            [
                np.min([p.mesh.bounds[0] for p in self.parts], axis=0),
                np.max([p.mesh.bounds[1] for p in self.parts], axis=0),
            ]
        )

    @cached_property
    def aabb(self) -> np.ndarray:
        """(2,3) world box of the transformed vertices (exact, not of the rotated local box).

        Cached: an instance's transform is fixed once placed (displacements make new transforms)."""
        pts = np.concatenate([p.mesh.vertices for p in self.parts]) @ self.transform[:3, :3].T + self.transform[:3, 3]
        return np.stack([pts.min(axis=0), pts.max(axis=0)])

    def to_object_info(self, transform: np.ndarray | None = None) -> ObjectInfo:
        T = self.transform if transform is None else transform
        pts = np.concatenate([p.mesh.vertices for p in self.parts]) @ T[:3, :3].T + T[:3, 3]
        aabb = np.round(np.stack([pts.min(axis=0), pts.max(axis=0)]), 5)
        attrs = dict(self.attributes)
        attrs["placement"] = self.placement
        return ObjectInfo(
            id=self.id,
            category=self.category,
            description=self.description,
            attributes=attrs,
            room=self.room,
            floor=self.floor,
            structural=self.structural,
            aabb=aabb.tolist(),
            transform=np.round(T, 9).tolist(),
        )


@dataclass
class Layout:
    """A whole scene: rooms, doors, lights and every placed instance."""

    rooms: list[Room]
    doors: list[Door]
    lights: list[Light]
    instances: list[Instance]
    footprint: tuple[float, float]
    """(length along x, depth along y) of the building."""
    floor_z: list[float]
    ceiling_height: float
    blocked: list[tuple[int, tuple[float, float, float, float]]] = field(default_factory=list)
    """(floor, rect) regions a camera must not enter (stairs, floor openings)."""

    def by_id(self) -> dict[int, Instance]:
        return {i.id: i for i in self.instances}

    def rooms_on(self, floor: int) -> list[Room]:
        return [r for r in self.rooms if r.floor == floor]

    def objects(self) -> list[ObjectInfo]:
        return [i.to_object_info() for i in self.instances]

    def room_graph(self) -> nx.Graph:
        """Rooms joined by doors (and stairs between floors)."""
        g = nx.Graph()
        g.add_nodes_from(r.name for r in self.rooms)
        g.add_edges_from(d.rooms for d in self.doors)
        return g


# ------------------------------------------------------------------------------------------------
# geometry helpers
# ------------------------------------------------------------------------------------------------


def box_mesh(lo: np.ndarray | tuple, hi: np.ndarray | tuple) -> trimesh.Trimesh:
    """Axis-aligned box between two corners."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return trimesh.creation.box(extents=hi - lo, transform=trimesh.transformations.translation_matrix((lo + hi) / 2))


def _slab_with_holes(
    rect: tuple[float, float, float, float], z0: float, z1: float, holes: list[tuple[float, float, float, float]]
) -> list[trimesh.Trimesh]:
    """Boxes covering ``rect`` minus rectangular ``holes`` (grid decomposition on the holes' edges)."""
    x0, y0, x1, y1 = rect
    xs = sorted({x0, x1, *[min(max(h[i], x0), x1) for h in holes for i in (0, 2)]})
    ys = sorted({y0, y1, *[min(max(h[i], y0), y1) for h in holes for i in (1, 3)]})
    boxes = []
    for xa, xb in zip(xs, xs[1:]):
        run_start = None
        for ya, yb in zip(ys, ys[1:]):
            cx, cy = (xa + xb) / 2, (ya + yb) / 2
            inside = any(h[0] < cx < h[2] and h[1] < cy < h[3] for h in holes)
            if not inside and run_start is None:
                run_start = ya
            if inside and run_start is not None:
                boxes.append(box_mesh((xa, run_start, z0), (xb, ya, z1)))
                run_start = None
        if run_start is not None:
            boxes.append(box_mesh((xa, run_start, z0), (xb, ys[-1], z1)))
    return [b for b in boxes if min(b.extents) > 1e-6]


def free_space(
    xs: np.ndarray,
    ys: np.ndarray,
    rooms: list[Room],
    doors: list[Door],
    boxes: np.ndarray,
    blocked: list[tuple[float, float, float, float]],
    z0: float,
) -> np.ndarray:
    """Where a camera may stand on a grid of cell centres (xs, ys): inside a room away from its walls,
    through doorways, and at least OBJECT_CLEARANCE from any obstructing object box or blocked rect.

    Used both while furnishing (to keep rooms walkable and connected) and for camera trajectories.
    """
    free = np.zeros(xs.shape, dtype=bool)
    for room in rooms:
        x0, y0, x1, y1 = room.rect
        m = WALL_CLEARANCE
        free |= (xs >= x0 + m) & (xs <= x1 - m) & (ys >= y0 + m) & (ys <= y1 - m)
    for d in doors:
        half_w, reach = DOOR_W / 2 - 0.15, WALL_T / 2 + WALL_CLEARANCE + 0.15
        hx, hy = (half_w, reach) if d.axis == 0 else (reach, half_w)
        free |= (np.abs(xs - d.centre[0]) <= hx) & (np.abs(ys - d.centre[1]) <= hy)
    occupied = np.zeros(xs.shape, dtype=bool)
    for box in np.asarray(boxes).reshape(-1, 2, 3):
        if box[0, 2] > z0 + CAMERA_TOP or box[1, 2] < z0 + 0.05:  # above every camera, or flat (rugs)
            continue
        occupied |= (xs >= box[0, 0]) & (xs <= box[1, 0]) & (ys >= box[0, 1]) & (ys <= box[1, 1])
    for rect in blocked:
        occupied |= (xs >= rect[0]) & (xs <= rect[2]) & (ys >= rect[1]) & (ys <= rect[3])
    if occupied.any():
        free &= ndimage.distance_transform_edt(~occupied) * GRID_RES > OBJECT_CLEARANCE
    return free


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


def _part(meshes: list[trimesh.Trimesh], material: str, colour: str, seed: int) -> Part:
    return Part(trimesh.util.concatenate(meshes), material, COLOURS[colour], seed)


# ------------------------------------------------------------------------------------------------
# floor plan
# ------------------------------------------------------------------------------------------------


@dataclass
class _Plan:
    """Cells of one floor in wall-centre coordinates."""

    cells: list[tuple[float, float, float, float]]
    kinds: list[str]


def _split_length(total: float, n: int, lo: float, rng: np.random.Generator) -> list[float]:
    w = lo + (total - n * lo) * rng.dirichlet(np.full(n, 4.0))
    return list(w)


def _plan_strips(spec: SceneSpec, rng: np.random.Generator) -> dict:
    """Footprint shared by every floor: strip depths, total length, per-floor room counts per strip."""
    n = spec.rooms
    corridor = n >= 5
    n_side = n - 1 if corridor else n
    n_top = (n_side + 1) // 2 if n_side > 1 else 1
    n_bot = n_side - n_top
    widths = [float(rng.uniform(spec.room_side_min, spec.room_side_max)) for _ in range(max(n_top, 1))]
    if spec.kind == "multi-floor":
        widths[0] = max(widths[0], STAIR_LEN + 0.6)
    L = float(sum(widths))
    if n_bot:
        L = max(L, n_bot * spec.room_side_min)
    shape = {
        "L": L,
        "corridor": corridor,
        "top_first": widths[0],
        "d_top": float(rng.uniform(spec.room_side_min, spec.room_side_max)),
        "d_bot": float(rng.uniform(spec.room_side_min, spec.room_side_max)) if n_bot else 0.0,
    }
    if spec.kind == "multi-floor":
        shape["d_top"] = max(shape["d_top"], STAIR_W + 2.0)
        if n_bot:
            shape["d_bot"] = max(shape["d_bot"], STAIR_W + 2.0)
    shape["counts"] = (n_top, n_bot)
    return shape


def _floor_cells(spec: SceneSpec, shape: dict, counts: tuple[int, int], rng: np.random.Generator) -> _Plan:
    n_top, n_bot = counts
    L, d_bot, d_top = shape["L"], shape["d_bot"], shape["d_top"]
    c = CORRIDOR_W if shape["corridor"] else 0.0
    cells: list[tuple[float, float, float, float]] = []
    kinds: list[str] = []
    y_top0 = d_bot + c
    first = shape["top_first"]
    top_w = [first] + (
        _split_length(L - first, n_top - 1, min(spec.room_side_min, (L - first) / max(n_top - 1, 1)), rng)
        if n_top > 1
        else []
    )
    if n_top == 1:
        top_w = [L]
    x = 0.0
    for w in top_w:
        cells.append((x, y_top0, x + w, y_top0 + d_top))
        x += w
    if n_bot:
        bot_w = _split_length(L, n_bot, min(spec.room_side_min, L / n_bot), rng)
        if spec.kind == "multi-floor" and n_bot > 1 and bot_w[0] < STAIR_LEN + 0.6:
            bot_w = [STAIR_LEN + 0.6] + _split_length(
                L - STAIR_LEN - 0.6, n_bot - 1, min(spec.room_side_min, (L - STAIR_LEN - 0.6) / (n_bot - 1)), rng
            )
        x = 0.0
        for w in bot_w:
            cells.append((x, 0.0, x + w, d_bot))
            x += w
    n_rooms = len(cells)
    pool = list(ROOM_KINDS_NO_CORRIDOR)
    order = rng.permutation(len(pool))
    # every kind once before any repeats; living rooms are the biggest cells
    kinds = [pool[order[i % len(pool)]] for i in range(n_rooms)]
    if shape["corridor"]:
        cells.append((0.0, d_bot, L, d_bot + c))
        kinds.append("corridor")
    return _Plan(cells, kinds)


def _shared_edge(a: tuple, b: tuple, min_len: float) -> tuple[int, float, float, float] | None:
    """(axis, fixed coord, lo, hi) of the wall two cells share, if long enough for a door."""
    for axis in (0, 1):  # axis 0: wall along x at y = const
        ia, ib = (1, 3) if axis == 0 else (0, 2)
        ja, jb = (0, 2) if axis == 0 else (1, 3)
        for fa, fb in ((a[ib], b[ia]), (a[ia], b[ib])):
            if abs(fa - fb) < 1e-6:
                lo, hi = max(a[ja], b[ja]), min(a[jb], b[jb])
                if hi - lo >= min_len:
                    return axis, fa, lo, hi
    return None


# ------------------------------------------------------------------------------------------------
# builder
# ------------------------------------------------------------------------------------------------


class _Builder:
    def __init__(self, spec: SceneSpec):
        self.spec = spec
        self.rng = np.random.default_rng(spec.seed)
        self.instances: list[Instance] = []
        self.rooms: list[Room] = []
        self.doors: list[Door] = []
        self.lights: list[Light] = []
        self.blocked: list[tuple[int, tuple[float, float, float, float]]] = []
        self.storey = spec.ceiling_height + STOREY_GAP
        self._empty_free: dict[str, int] = {}
        self.library = library_for(spec)

    def tex_seed(self) -> int:
        return int(self.rng.integers(1 << 30))

    def add(self, **kw) -> Instance:
        inst = Instance(id=len(self.instances) + 1, **kw)
        self.instances.append(inst)
        return inst

    # structure ----------------------------------------------------------------------------------

    def build(self) -> Layout:
        spec = self.spec
        shape = _plan_strips(spec, self.rng)
        counts = shape["counts"]
        depth = shape["d_bot"] + (CORRIDOR_W if shape["corridor"] else 0.0) + shape["d_top"]
        footprint = (shape["L"], depth)
        stair_cells: list[tuple[float, float, float, float]] = []  # stair rect for floor f -> f+1
        for f in range(spec.floors):
            plan = _floor_cells(spec, shape, counts, self.rng)
            self._build_floor(f, plan, footprint, stair_cells)
        for f in range(spec.floors):
            for room in self.rooms_on(f):
                self._furnish(room)
        floor_z = [f * self.storey for f in range(spec.floors)]
        return Layout(
            self.rooms, self.doors, self.lights, self.instances, footprint, floor_z, spec.ceiling_height, self.blocked
        )

    def rooms_on(self, f: int) -> list[Room]:
        return [r for r in self.rooms if r.floor == f]

    def _build_floor(self, f: int, plan: _Plan, footprint: tuple[float, float], stair_cells: list) -> None:
        spec, rng = self.spec, self.rng
        z0 = f * self.storey
        H = spec.ceiling_height
        h = WALL_T / 2
        names = []
        counters: dict[str, int] = {}
        for cell, kind in zip(plan.cells, plan.kinds):
            counters[kind] = counters.get(kind, 0) + 1
            name = f"f{f}_{kind}_{counters[kind]}" if spec.floors > 1 else f"{kind}_{counters[kind]}"
            names.append(name)
            self.rooms.append(Room(name, kind, f, (cell[0] + h, cell[1] + h, cell[2] - h, cell[3] - h), z0, H))
        rooms = self.rooms[-len(plan.cells) :]
        wall_colour = {r.name: _WALL_COLOURS[int(rng.integers(len(_WALL_COLOURS)))] for r in rooms}
        # stairs: up from this floor (in the first cell of the top / bottom strip), opening from below
        holes_floor: dict[int, list] = {i: [] for i in range(len(rooms))}
        holes_ceiling: dict[int, list] = {i: [] for i in range(len(rooms))}
        stair_here = None
        if f < spec.floors - 1:
            top = f % 2 == 0 or not any(cell[1] == 0.0 for cell in plan.cells)
            idx = next(
                i
                for i, cell in enumerate(plan.cells)
                if (cell[3] == footprint[1] if top else cell[1] == 0.0) and plan.kinds[i] != "corridor"
            )
            r = rooms[idx].rect
            sx0 = r[0] + 0.3
            rect = (sx0, r[3] - STAIR_W, sx0 + STAIR_LEN, r[3]) if top else (sx0, r[1], sx0 + STAIR_LEN, r[1] + STAIR_W)
            stair_cells.append(rect)
            stair_here = (idx, rect, top)
            holes_ceiling[idx].append(rect)
        if f > 0:
            below = stair_cells[f - 1]
            for i, room in enumerate(rooms):
                if room.contains_xy(np.array([(below[0] + below[2]) / 2, (below[1] + below[3]) / 2])):
                    holes_floor[i].append(below)
                    self._railing(room, below, z0)
                    self.blocked.append((f, below))
        # slabs
        for i, (cell, room) in enumerate(zip(plan.cells, rooms)):
            fkind = _FLOOR_MATERIAL[room.kind]
            fcol = _FLOOR_COLOURS[int(rng.integers(len(_FLOOR_COLOURS)))]
            self.add(
                category="floor",
                parts=[_part(_slab_with_holes(cell, z0 - SLAB_T, z0, holes_floor[i]), fkind, fcol, self.tex_seed())],
                transform=np.eye(4),
                structural=True,
                room=room.name,
                floor=f,
                description=f"a {fcol} {fkind} floor",
                attributes={"colour": fcol, "material": fkind},
            )
            self.add(
                category="ceiling",
                parts=[
                    _part(
                        _slab_with_holes(cell, z0 + H, z0 + H + SLAB_T, holes_ceiling[i]),
                        "plaster",
                        "white",
                        self.tex_seed(),
                    )
                ],
                transform=np.eye(4),
                structural=True,
                room=room.name,
                floor=f,
                description="a white plaster ceiling",
                attributes={"colour": "white", "material": "plaster"},
            )
        if stair_here is not None:
            self._stairs(rooms[stair_here[0]], stair_here[1], stair_here[2], z0)
            self.blocked.append((f, stair_here[1]))
        # doors: spanning tree of the adjacency graph (corridor first) plus a few extra loops
        g = nx.Graph()
        g.add_nodes_from(range(len(rooms)))
        for i in range(len(rooms)):
            for j in range(i + 1, len(rooms)):
                e = _shared_edge(plan.cells[i], plan.cells[j], DOOR_W + 0.8)
                if e is not None:
                    is_corr = "corridor" in (plan.kinds[i], plan.kinds[j])
                    g.add_edge(i, j, edge=e, weight=float(rng.uniform(0, 1)) - (2.0 if is_corr else 0.0))
        tree = nx.minimum_spanning_tree(g)
        door_edges = set(tree.edges())
        for i, j in sorted(g.edges()):
            if (i, j) not in door_edges and (j, i) not in door_edges and rng.random() < 0.25:
                door_edges.add((i, j))
        doors_on_line: list[tuple[int, float, float, float]] = []  # axis, fixed, lo, hi of openings
        for i, j in sorted(tuple(sorted(e)) for e in door_edges):
            axis, fixed, lo, hi = g.edges[i, j]["edge"]
            stair_rects = [stair_here[1]] if stair_here else []
            if f > 0:
                stair_rects.append(stair_cells[f - 1])
            for _ in range(20):
                centre = float(rng.uniform(lo + 0.4 + DOOR_W / 2, hi - 0.4 - DOOR_W / 2))
                p = np.array([centre, fixed]) if axis == 0 else np.array([fixed, centre])
                clear = all(
                    not (s[0] - 0.9 < p[0] < s[2] + 0.9 and s[1] - 0.9 < p[1] < s[3] + 0.9) for s in stair_rects
                )
                if clear:
                    break
            doors_on_line.append((axis, fixed, centre - DOOR_W / 2, centre + DOOR_W / 2))
            self.doors.append(Door(f, np.array([p[0], p[1], z0]), axis, (rooms[i].name, rooms[j].name)))
        # walls: every cell edge split at the breakpoints of all cells on the same line
        self._walls(f, plan, rooms, wall_colour, doors_on_line, z0, H, footprint)
        # lights: one per room, two along the long axis of big rooms
        for room in rooms:
            x0, y0, x1, y1 = room.rect
            n_l = 2 if room.area > 18 else 1
            long_x = (x1 - x0) >= (y1 - y0)
            for k in range(n_l):
                t = (k + 1) / (n_l + 1)
                pos = (x0 + t * (x1 - x0), (y0 + y1) / 2) if long_x else ((x0 + x1) / 2, y0 + t * (y1 - y0))
                self.lights.append(Light(np.array([pos[0], pos[1], z0 + H - 0.35]), room.name, f))

    def _walls(self, f, plan, rooms, wall_colour, openings, z0, H, footprint) -> None:
        rng = self.rng
        lines: dict[tuple[int, float], set[float]] = {}
        for cell in plan.cells:
            for axis, fixed, lo, hi in (
                (0, cell[1], cell[0], cell[2]),
                (0, cell[3], cell[0], cell[2]),
                (1, cell[0], cell[1], cell[3]),
                (1, cell[2], cell[1], cell[3]),
            ):
                key = (axis, round(fixed, 6))
                lines.setdefault(key, set()).update((round(lo, 6), round(hi, 6)))
        h = WALL_T / 2
        for (axis, fixed), pts in sorted(lines.items()):
            pts_sorted = sorted(pts)
            for a, b in zip(pts_sorted, pts_sorted[1:]):
                mid = (a + b) / 2
                sides = []
                for sgn in (-1, 1):
                    probe = np.array([mid, fixed + sgn * 0.2]) if axis == 0 else np.array([fixed + sgn * 0.2, mid])
                    sides.append(next((r for r in rooms if r.contains_xy(probe)), None))
                if sides[0] is None and sides[1] is None:
                    continue
                holes = [
                    (o[2], o[3])
                    for o in openings
                    if o[0] == axis and abs(o[1] - fixed) < 1e-6 and a <= o[2] and o[3] <= b
                ]
                outer = sides[0] is None or sides[1] is None
                window = None
                if outer and not holes and b - a > 2.2 and rng.random() < 0.7:
                    wc = float(rng.uniform(a + 1.0, b - 1.0))
                    ww = float(min(rng.uniform(0.8, 1.6), 2 * min(wc - a - 0.4, b - wc - 0.4)))
                    window = (wc - ww / 2, wc + ww / 2)
                # along-wall extent: walls along x cover the corners
                ea, eb = (a - h, b + h) if axis == 0 else (a + h, b - h)
                parts = []
                for k, room in enumerate(sides):
                    if room is None:
                        continue
                    off = (-h, 0.0) if k == 0 else (0.0, h)
                    pieces = self._wall_pieces(axis, fixed + off[0], fixed + off[1], ea, eb, holes, z0, H)
                    parts.append(_part(pieces, "plaster", wall_colour[room.name], self.tex_seed()))
                outer_side = [k for k in (0, 1) if sides[k] is None]
                for k in outer_side:  # exterior face: plain grey render
                    off = (-h, 0.0) if k == 0 else (0.0, h)
                    parts.append(
                        _part(
                            self._wall_pieces(axis, fixed + off[0], fixed + off[1], ea, eb, holes, z0, H),
                            "plaster",
                            "light grey",
                            self.tex_seed(),
                        )
                    )
                named = [s.name for s in sides if s is not None]
                self.add(
                    category="wall",
                    parts=parts,
                    transform=np.eye(4),
                    structural=True,
                    room=named[0],
                    floor=f,
                    description=f"a {wall_colour[named[0]]} plaster wall",
                    attributes={"colour": wall_colour[named[0]], "material": "plaster", "rooms": ",".join(named)},
                )
                for lo, hi in holes:
                    self._door_frame(axis, fixed, lo, hi, z0, f, named)
                if window is not None:
                    inside = 0 if sides[0] is not None else 1
                    self._window(axis, fixed, window, z0, f, sides[inside], inside)

    @staticmethod
    def _wall_pieces(axis, t0, t1, a, b, holes, z0, H) -> list[trimesh.Trimesh]:
        """Boxes of one wall face layer between along-wall coords a..b, thickness t0..t1, with door holes."""

        def mk(u0, u1, za, zb):
            return box_mesh((u0, t0, za), (u1, t1, zb)) if axis == 0 else box_mesh((t0, u0, za), (t1, u1, zb))

        out, u = [], a
        for lo, hi in sorted(holes):
            out.append(mk(u, lo, z0, z0 + H))
            out.append(mk(lo, hi, z0 + DOOR_H, z0 + H))
            u = hi
        out.append(mk(u, b, z0, z0 + H))
        return [m for m in out if min(m.extents) > 1e-6]

    def _door_frame(self, axis, fixed, lo, hi, z0, f, rooms) -> None:
        depth, w = WALL_T + 0.04, 0.06

        def mk(u0, u1, za, zb):
            t0, t1 = fixed - depth / 2, fixed + depth / 2
            return box_mesh((u0, t0, za), (u1, t1, zb)) if axis == 0 else box_mesh((t0, u0, za), (t1, u1, zb))

        meshes = [
            mk(lo, lo + w, z0, z0 + DOOR_H),
            mk(hi - w, hi, z0, z0 + DOOR_H),
            mk(lo, hi, z0 + DOOR_H - w, z0 + DOOR_H),
        ]
        colour = ("white", "brown", "dark brown", "light brown")[int(self.rng.integers(4))]
        self.add(
            category="door",
            parts=[_part(meshes, "wood", colour, self.tex_seed())],
            transform=np.eye(4),
            structural=True,
            room=rooms[0],
            floor=f,
            description=f"a {colour} wooden door frame",
            attributes={"colour": colour, "material": "wood", "rooms": ",".join(rooms)},
        )

    def _window(self, axis, fixed, span, z0, f, room: Room, inside: int) -> None:
        sgn = -1 if inside == 0 else 1
        t_in = fixed + sgn * WALL_T / 2  # inner wall surface
        za, zb = z0 + 0.9, z0 + 2.1

        def mk(u0, u1, z_0, z_1, d0, d1):
            t0, t1 = sorted((t_in + sgn * d0, t_in + sgn * d1))
            return box_mesh((u0, t0, z_0), (u1, t1, z_1)) if axis == 0 else box_mesh((t0, u0, z_0), (t1, u1, z_1))

        lo, hi = span
        fw = 0.05
        frame = [
            mk(lo, hi, za, za + fw, 0, 0.05),
            mk(lo, hi, zb - fw, zb, 0, 0.05),
            mk(lo, lo + fw, za, zb, 0, 0.05),
            mk(hi - fw, hi, za, zb, 0, 0.05),
            mk(lo, hi, (za + zb) / 2 - 0.02, (za + zb) / 2 + 0.02, 0, 0.04),
            mk(lo - 0.05, hi + 0.05, za - 0.04, za, 0, 0.12),
        ]
        pane = [mk(lo + fw, hi - fw, za + fw, zb - fw, 0, 0.02)]
        self.add(
            category="window",
            parts=[
                _part(frame, "plastic", "white", self.tex_seed()),
                _part(pane, "glass", "light blue", self.tex_seed()),
            ],
            transform=np.eye(4),
            structural=True,
            room=room.name,
            floor=f,
            description="a white framed window",
            attributes={"colour": "white", "material": "glass"},
        )

    def _stairs(self, room: Room, rect, top: bool, z0: float) -> None:
        n = 16
        rise, run = self.storey / n, STAIR_LEN / n
        x0, y0, x1, y1 = rect
        steps = [box_mesh((x0 + i * run, y0, z0), (x0 + (i + 1) * run, y1, z0 + (i + 1) * rise)) for i in range(n)]
        colour = ("grey", "brown", "light brown")[int(self.rng.integers(3))]
        self.add(
            category="stairs",
            parts=[_part(steps, "wood" if colour != "grey" else "stone", colour, self.tex_seed())],
            transform=np.eye(4),
            structural=True,
            room=room.name,
            floor=room.floor,
            description=f"a straight {colour} staircase",
            attributes={"colour": colour, "material": "wood"},
        )

    def _railing(self, room: Room, hole, z0: float) -> None:
        x0, y0, x1, y1 = hole
        inner_y = y0 if abs(y1 - room.rect[3]) < 1e-6 else y1
        posts = [
            box_mesh((x - 0.02, inner_y - 0.02, z0), (x + 0.02, inner_y + 0.02, z0 + 1.0))
            for x in np.linspace(x0, x1, 9)
        ]
        posts.append(box_mesh((x0 - 0.03, inner_y - 0.03, z0 + 0.95), (x1 + 0.03, inner_y + 0.03, z0 + 1.0)))
        ya, yb = sorted((y0, y1))
        posts += [box_mesh((x0 - 0.02, y - 0.02, z0), (x0 + 0.02, y + 0.02, z0 + 1.0)) for y in np.linspace(ya, yb, 4)]
        posts.append(box_mesh((x0 - 0.03, ya, z0 + 0.95), (x0 + 0.03, yb, z0 + 1.0)))
        self.add(
            category="railing",
            parts=[_part(posts, "metal", "dark grey", self.tex_seed())],
            transform=np.eye(4),
            structural=True,
            room=room.name,
            floor=room.floor,
            description="a dark grey metal railing",
            attributes={"colour": "dark grey", "material": "metal"},
        )

    # furniture ----------------------------------------------------------------------------------

    def _occupied(self, room: Room) -> _Boxes:
        """Boxes furniture must avoid: this room's stairs and railings (door frames and windows are kept
        clear by the door and window zones; objects are added as they are placed)."""
        return _Boxes(
            [
                (i.id, i.aabb)
                for i in self.instances
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
        doors = [d for d in self.doors if room.name in d.rooms]
        blocked = [rect for f, rect in self.blocked if f == room.floor]
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
        for d in self.doors:
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
        return [i.aabb for i in self.instances if i.category == "window" and i.room == room.name]

    def _pick(self, room: Room, placement: str) -> str | None:
        cats = self.library.categories(room.kind, placement)
        if not cats:
            return None
        w = np.array([c.weight for c in cats], float)
        return cats[int(self.rng.choice(len(cats), p=w / w.sum()))].name

    def _place_instance(self, asset: Asset, room: Room, T: np.ndarray, support: int | None = None) -> Instance:
        return self.add(
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

    def _furnish(self, room: Room) -> None:
        rng = self.rng
        target = self.spec.objects_per_room
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
        for light in [li for li in self.lights if li.room == room.name]:
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


def build_layout(spec: SceneSpec) -> Layout:
    """Deterministic layout of ``spec`` (same spec and seed -> identical layout)."""
    return _Builder(spec).build()
