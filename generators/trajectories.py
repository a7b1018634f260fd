"""Camera paths: an occupancy grid per floor, a mapping scan through every room, and query poses.

Mapping: per floor, rooms are visited in depth-first order of the door graph; in each room the camera
walks a loop inset from the walls looking towards the room centre (with a slow yaw sweep), so every
wall and the objects against it are seen from across the room; rooms are joined by shortest paths
through the doorways on the grid. A frame is emitted every ``mapping_step_m`` of travel or
``mapping_step_deg`` of rotation.

Queries: random free-space positions at 0.9-1.9 m with random yaw, varied pitch and a little roll,
kept only if far enough in position / orientation from every mapping frame (the viewpoint change is
recorded per query) and if enough non-structural objects are visible (checked by rendering instance
ids at low resolution). ``query_near`` poses lie on the mapping path between consecutive frames
(:func:`sample_near_queries`). ``query_walk`` is a second walk through the rooms of one floor
(:func:`sample_walk`): the mapping route's pieces (room order, room loops, links) from another start, on
loops nearer the room centres walked the other way, looking ahead with a hand-held sweep.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

import networkx as nx
import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from generators.layout import Layout, Room
from generators.layout.free_space import GRID_RES, WALL_CLEARANCE, free_space
from generators.render import Renderer
from generators.spec import SceneSpec
from openreloc_bench import geometry

QUERY_HEIGHT = (0.9, 1.9)
MAPPING_HEIGHT = (1.2, 1.7)
CHECK_WIDTH = 160
"""Width of the low-resolution instance render used for the query visibility check."""
MIN_OBJECT_SHARE = 0.005
"""An object counts as visible when it covers at least this share of the image."""
MAPPING_INSET = (0.25, 1.1)
"""The mapping loop's inset from a room's walls: this share of the room's shorter side, at most this (m)."""
WALK_INSET = (0.33, 1.4)
"""``query_walk``'s loop: nearer the room's centre than the mapping's, so the walk takes another route."""
NEAR_QUERY_ROUNDS = 4
"""Most ``query_near`` poses taken from one gap between mapping frames (short paths need several)."""


@dataclass
class Occupancy:
    """Free space of one floor: ``free[row, col]`` with row along y and col along x."""

    floor: int
    origin: np.ndarray
    free: np.ndarray
    room_index: np.ndarray
    """Index into ``rooms`` of the room containing each cell (-1 outside every room)."""
    rooms: list[Room]

    def cell(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ij = np.floor((np.atleast_2d(xy) - self.origin) / GRID_RES).astype(int)
        return ij[:, 1], ij[:, 0]

    def centre(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        return self.origin + (np.stack([cols, rows], axis=-1) + 0.5) * GRID_RES

    def is_free(self, xy: np.ndarray) -> np.ndarray:
        r, c = self.cell(xy)
        ok = (r >= 0) & (c >= 0) & (r < self.free.shape[0]) & (c < self.free.shape[1])
        out = np.zeros(len(r), dtype=bool)
        out[ok] = self.free[r[ok], c[ok]]
        return out


def occupancy_grid(layout: Layout, floor: int) -> Occupancy:
    """Cells where a camera may stand: inside a room away from walls, outside object footprints, through doors."""
    length, depth = layout.footprint
    origin = np.array([-0.5, -0.5])
    shape = (int(np.ceil((depth + 1.0) / GRID_RES)), int(np.ceil((length + 1.0) / GRID_RES)))
    ys, xs = (np.indices(shape) + 0.5) * GRID_RES
    xs, ys = xs + origin[0], ys + origin[1]
    rooms = layout.rooms_on(floor)
    room_index = np.full(shape, -1, dtype=int)
    for k, room in enumerate(rooms):
        x0, y0, x1, y1 = room.rect
        room_index[(xs >= x0) & (xs <= x1) & (ys >= y0) & (ys <= y1)] = k
    boxes = np.array(
        [
            i.aabb
            for i in layout.instances
            if i.floor == floor and i.category not in ("wall", "floor", "ceiling", "door", "window")
        ]
    ).reshape(-1, 2, 3)
    free = free_space(
        xs,
        ys,
        rooms,
        [d for d in layout.doors if d.floor == floor],
        boxes,
        [rect for f, rect in layout.blocked if f == floor],
        layout.floor_z[floor],
    )
    return Occupancy(floor, origin, free, room_index, rooms)


def grid_graph(occ: Occupancy):
    """8-connected graph of free cells (sparse matrix) and the flat index of each free cell."""
    rows, cols = occ.free.shape
    idx = np.full(occ.free.shape, -1, dtype=int)
    fr, fc = np.nonzero(occ.free)
    idx[fr, fc] = np.arange(len(fr))
    src, dst, w = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        r2, c2 = fr + dr, fc + dc
        ok = (r2 >= 0) & (r2 < rows) & (c2 >= 0) & (c2 < cols)
        ok[ok] &= occ.free[r2[ok], c2[ok]]
        src.append(idx[fr[ok], fc[ok]])
        dst.append(idx[r2[ok], c2[ok]])
        w.append(np.full(ok.sum(), np.hypot(dr, dc)))
    n = len(fr)
    g = coo_matrix((np.concatenate(w), (np.concatenate(src), np.concatenate(dst))), shape=(n, n)).tocsr()
    return g, idx, np.stack([fr, fc], axis=1)


class _PathFinder:
    def __init__(self, occ: Occupancy):
        self.occ = occ
        self.graph, self.idx, self.cells = grid_graph(occ)

    def path(self, a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
        """Shortest free-space path from a to b (world xy), as cell centres."""
        ra, ca = self.occ.cell(a)
        rb, cb = self.occ.cell(b)
        ia, ib = self.idx[ra[0], ca[0]], self.idx[rb[0], cb[0]]
        if ia < 0 or ib < 0:
            return None
        dist, pred = dijkstra(self.graph, directed=False, indices=ia, return_predecessors=True)
        if not np.isfinite(dist[ib]):
            return None
        chain = [ib]
        while chain[-1] != ia:
            chain.append(pred[chain[-1]])
        cells = self.cells[chain[::-1]]
        return self.occ.centre(cells[:, 0], cells[:, 1])


def walkable_region(occ: Occupancy) -> np.ndarray:
    """bool grid: the floor's largest connected free region. Mapping paths stay in it (so paths always
    exist) and queries are drawn from it, so every query stands where the mapping sequence could go."""
    labels, n = ndimage.label(occ.free, structure=np.ones((3, 3)))
    if not n:
        return np.zeros_like(occ.free)
    return labels == np.bincount(labels.ravel(), minlength=2)[1:].argmax() + 1


def _snap_free(occ: Occupancy, region: np.ndarray, pts: np.ndarray, room_k: int) -> np.ndarray:
    """Move points to the nearest cell of the same room in the floor's walkable ``region``."""
    ok = region & (occ.room_index == room_k)
    if not ok.any():
        return np.empty((0, 2))
    _, (ri, ci) = ndimage.distance_transform_edt(~ok, return_indices=True)
    r, c = occ.cell(pts)
    r = np.clip(r, 0, ok.shape[0] - 1)
    c = np.clip(c, 0, ok.shape[1] - 1)
    snapped = occ.centre(ri[r, c], ci[r, c])
    keep = np.r_[True, np.any(np.abs(np.diff(snapped, axis=0)) > 1e-9, axis=1)]
    return snapped[keep]


def _room_loop(
    occ: Occupancy,
    region: np.ndarray,
    k: int,
    room: Room,
    start: np.ndarray,
    inset: tuple[float, float],
    clockwise: bool,
) -> np.ndarray:
    """A closed loop around room ``k`` inset from its walls by ``inset`` (share of the room's shorter side, at
    most this many metres), counter-clockwise or ``clockwise``, from the point nearest ``start``."""
    x0, y0, x1, y1 = room.rect
    margin = float(np.clip(inset[0] * min(x1 - x0, y1 - y0), WALL_CLEARANCE + 0.1, inset[1]))
    corners = np.array(
        [
            [x0 + margin, y0 + margin],
            [x1 - margin, y0 + margin],
            [x1 - margin, y1 - margin],
            [x0 + margin, y1 - margin],
        ]
    )
    if clockwise:
        corners = corners[::-1]
    ring = np.vstack([corners, corners[:1]])
    seg = np.linalg.norm(np.diff(ring, axis=0), axis=1)
    s = np.arange(0, seg.sum(), GRID_RES)
    pts = np.stack([np.interp(s, np.r_[0, np.cumsum(seg)], ring[:, i]) for i in range(2)], axis=1)
    first = int(np.argmin(np.linalg.norm(pts - start, axis=1)))
    pts = np.roll(pts, -first, axis=0)
    return _snap_free(occ, region, np.vstack([pts, pts[:1]]), k)


def _line_free(occ: Occupancy, a: np.ndarray, b: np.ndarray) -> bool:
    n = max(2, int(np.linalg.norm(b - a) / (GRID_RES / 2)) + 1)
    return bool(occ.is_free(np.linspace(a, b, n)).all())


def _densify(occ: Occupancy, finder: _PathFinder, pts: np.ndarray) -> np.ndarray:
    """Join consecutive points by straight lines where free, else by grid shortest paths."""
    out = [pts[:1]]
    for a, b in zip(pts[:-1], pts[1:]):
        if np.linalg.norm(b - a) <= 1.5 * GRID_RES or _line_free(occ, a, b):
            out.append(b[None])
            continue
        p = finder.path(a, b)
        if p is not None:
            out.append(p[1:])
    return np.vstack(out)


def _pose(eye: np.ndarray, yaw: float, pitch: float, roll: float = 0.0) -> np.ndarray:
    fwd = np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)])
    T = geometry.look_at(eye, eye + fwd)
    if roll:
        c, s = np.cos(roll), np.sin(roll)
        T = T @ geometry.make_pose(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]), np.zeros(3))
    return T


def _resample(samples: list, spacing: float) -> list:
    """Resample grid-step paths to a fine even spacing (per floor) so frame spacing tracks the spec."""
    out = []
    floors = np.array([s[2] for s in samples])
    for f in np.unique(floors):
        idx = np.flatnonzero(floors == f)
        xy = np.array([samples[i][0] for i in idx])
        s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))]
        t = np.arange(0.0, s[-1] + 1e-9, spacing)
        nearest = np.clip(np.searchsorted(s, t, side="right") - 1, 0, len(idx) - 1)
        fine = np.stack([np.interp(t, s, xy[:, 0]), np.interp(t, s, xy[:, 1])], axis=1)
        out += [(p, samples[idx[j]][1], int(f)) for p, j in zip(fine, nearest)]
    return out


def _room_order(layout: Layout, rooms: list[Room], first: int) -> list[int]:
    """Indices into ``rooms`` (one floor's): depth-first through the door graph from ``rooms[first]``, then
    the rooms it does not reach."""
    g = layout.room_graph().subgraph(r.name for r in rooms)
    index = {r.name: k for k, r in enumerate(rooms)}
    order = [index[name] for name in nx.dfs_preorder_nodes(g, rooms[first].name)]
    return order + [k for k in range(len(rooms)) if k not in order]


def _route(
    occ: Occupancy,
    region: np.ndarray,
    order: list[int],
    start: np.ndarray | None,
    inset: tuple[float, float],
    clockwise: bool,
) -> list[tuple[np.ndarray, Room | None, int]]:
    """A camera route through the rooms ``order`` of ``occ``'s floor, ~GRID_RES apart: a loop in each room
    (:func:`_room_loop`), the first from the point nearest ``start`` (default: the room's centre), each
    joined to the next by the shortest path. Samples are (xy, room or None on the links between rooms, floor)."""
    finder = _PathFinder(occ)
    samples: list[tuple[np.ndarray, Room | None, int]] = []
    pos = None
    for k in order:
        room = occ.rooms[k]
        begin = pos if pos is not None else (room.centre[:2] if start is None else start)
        loop = _room_loop(occ, region, k, room, begin, inset, clockwise)
        if len(loop) < 2:
            continue
        if pos is not None:
            link = finder.path(pos, loop[0])
            if link is not None and len(link) > 1:
                for p in link[1:-1]:
                    samples.append((p, None, occ.floor))
        loop = _densify(occ, finder, loop)
        for p in loop:
            samples.append((p, room, occ.floor))
        pos = loop[-1]
    return samples


def _travelled(xy: np.ndarray) -> np.ndarray:
    """Distance travelled along a path (m) at each of its points."""
    return np.cumsum(np.r_[0.0, np.linalg.norm(np.diff(xy, axis=0), axis=1)])


def _camera_height(dist: np.ndarray, phase: float, period_m: float) -> np.ndarray:
    """Height above the floor of a hand-held camera, bobbing within :data:`MAPPING_HEIGHT` along the path."""
    return np.mean(MAPPING_HEIGHT) + 0.5 * np.diff(MAPPING_HEIGHT)[0] * np.sin(2 * np.pi * dist / period_m + phase)


def _travel_heading(xy: np.ndarray, i: int, still: float) -> float:
    """Direction of travel at point ``i`` of a fine path (over 12 points either side); ``still`` where the
    path does not move."""
    d = xy[min(i + 12, len(xy) - 1)] - xy[max(i - 12, 0)]
    return np.arctan2(d[1], d[0]) if np.linalg.norm(d) > 1e-6 else still


def _smooth_orientation(
    yaw: np.ndarray, pitch: np.ndarray, floors: np.ndarray, window: int = 25
) -> tuple[np.ndarray, np.ndarray]:
    """Yaw (unwrapped) and pitch averaged over ``window`` points of a fine path within each floor: a hand-held
    camera turns smoothly (25 points: ~0.6 m)."""
    yaw = np.unwrap(yaw)
    kernel = np.ones(window) / window
    for f in np.unique(floors):
        m = floors == f
        yaw[m] = ndimage.convolve1d(yaw[m], kernel, mode="nearest")
        pitch[m] = ndimage.convolve1d(pitch[m], kernel, mode="nearest")
    return yaw, pitch


def mapping_trajectory(layout: Layout, spec: SceneSpec) -> np.ndarray:
    """Mapping poses (N,4,4) through every room of every floor."""
    path, frames = mapping_path(layout, spec)
    return path[frames]


def mapping_path(layout: Layout, spec: SceneSpec) -> tuple[np.ndarray, np.ndarray]:
    """The mapping camera's whole path (M,4,4), a pose every quarter grid cell of travel, and the indices
    (N,) of the poses emitted as mapping frames."""
    rng = np.random.default_rng([spec.seed, 11])
    samples = []  # (xy, room or None for links between rooms, floor), ~GRID_RES apart
    for f in range(len(layout.floor_z)):
        occ = occupancy_grid(layout, f)
        region = walkable_region(occ)  # labelled once per floor, not once per room
        samples += _route(occ, region, _room_order(layout, occ.rooms, 0), None, MAPPING_INSET, clockwise=False)
    if not samples:
        raise RuntimeError("no free space for a mapping trajectory (rooms too cluttered)")
    samples = _resample(samples, GRID_RES / 4)
    xy = np.array([s[0] for s in samples])
    floors = np.array([s[2] for s in samples])
    dist = _travelled(xy)
    phase = rng.uniform(0, 2 * np.pi, 2)
    z = np.array([layout.floor_z[f] for f in floors]) + _camera_height(dist, phase[0], 7.0)
    yaw = np.empty(len(xy))
    pitch = np.empty(len(xy))
    for i, (p, room, _) in enumerate(samples):
        if room is not None:
            d = room.centre[:2] - p
            yaw[i] = np.arctan2(d[1], d[0]) + np.radians(35) * np.sin(2 * np.pi * dist[i] / 3.0 + phase[1])
            pitch[i] = np.arctan2(room.z0 + 0.8 - z[i], max(np.linalg.norm(d), 0.5))
        else:
            yaw[i] = _travel_heading(xy, i, yaw[i - 1] if i else 0.0)
            pitch[i] = np.radians(-10)
    yaw, pitch = _smooth_orientation(yaw, pitch, floors)
    pitch = np.clip(pitch, np.radians(-35), np.radians(5))
    poses = [_pose(np.r_[xy[i], z[i]], yaw[i], pitch[i]) for i in range(len(xy))]
    keep = [0]
    for i in range(1, len(poses)):
        last = poses[keep[-1]]
        moved = np.linalg.norm(poses[i][:3, 3] - last[:3, 3])
        turned = geometry.rotation_error(last, poses[i])
        if moved >= spec.mapping_step_m or turned >= spec.mapping_step_deg or floors[i] != floors[keep[-1]]:
            keep.append(i)
    frames = np.array(keep)
    if spec.max_mapping_frames and len(frames) > spec.max_mapping_frames:
        frames = frames[np.round(np.linspace(0, len(frames) - 1, spec.max_mapping_frames)).astype(int)]
    return np.array(poses), frames


def sample_walk(layout: Layout, spec: SceneSpec) -> np.ndarray:
    """``query_walk`` poses (n_query,4,4): the frames of a second recording of the rooms on another route
    than the mapping's, as 7-Scenes' and 12-Scenes' test sequences are. It starts at a random point of a
    random room and stays on its floor (a sequence does not jump between storeys); the rooms follow
    depth-first from there, each walked round clockwise on a loop nearer its centre (:data:`WALK_INSET`),
    the camera looking where it goes with a hand-held sweep of yaw and pitch. Consecutive frames are as
    close as the mapping's: one ``mapping_step_m`` of travel or ``mapping_step_deg`` of turning apart,
    whichever comes first (evenly along the whole route when it is shorter). Frames stand on the walkable
    region the mapping covers, but not at the random queries' minimum distance and angle from the mapping
    frames (``difficulty.csv`` records each frame's). Deterministic in the seed, on a random stream of its
    own."""
    rng = np.random.default_rng([spec.seed, 31])
    first = layout.rooms[int(rng.integers(len(layout.rooms)))]
    occ = occupancy_grid(layout, first.floor)
    k = next(i for i, r in enumerate(occ.rooms) if r.name == first.name)
    x0, y0, x1, y1 = first.rect
    start = rng.uniform([x0, y0], [x1, y1])
    samples = _route(occ, walkable_region(occ), _room_order(layout, occ.rooms, k), start, WALK_INSET, clockwise=True)
    if not samples:
        raise RuntimeError("no free space for the query_walk route (rooms too cluttered)")
    xy = np.array([s[0] for s in _resample(samples, GRID_RES / 4)])
    dist = _travelled(xy)
    phase = rng.uniform(0, 2 * np.pi, 3)
    yaw = np.empty(len(xy))
    for i in range(len(xy)):
        yaw[i] = _travel_heading(xy, i, yaw[i - 1] if i else 0.0)
    yaw += np.radians(30) * np.sin(2 * np.pi * dist / 6.0 + phase[1])  # looking around while walking
    pitch = np.radians(-12.0 + 10.0 * np.sin(2 * np.pi * dist / 4.0 + phase[2]))
    yaw, pitch = _smooth_orientation(yaw, pitch, np.zeros(len(xy)), window=61)  # ~1.5 m: rounded corners
    z = layout.floor_z[first.floor] + _camera_height(dist, phase[0], 5.0)
    reach = np.searchsorted(dist, (spec.n_query - 1) * spec.mapping_step_m, side="right")  # the frames' part
    path = np.array([_pose(np.r_[xy[i], z[i]], yaw[i], pitch[i]) for i in range(reach)])
    turned = geometry.rotation_error(path[:-1], path[1:])
    steps = np.maximum(np.diff(dist[:reach]) / spec.mapping_step_m, turned / spec.mapping_step_deg)
    motion = np.r_[0.0, np.cumsum(steps)]
    picks = np.searchsorted(motion, np.linspace(0.0, min(motion[-1], spec.n_query - 1.0), spec.n_query), side="right")
    return path[picks - 1]


@dataclass
class QueryInfo:
    """How a query differs from the mapping frames (recorded in scene.json)."""

    nearest_mapping: int
    """Index of the mapping frame with the nearest camera centre."""
    distance_m: float
    """Distance to that frame's camera centre."""
    angle_deg: float
    """Rotation to that frame."""
    min_angle_within_1m_deg: float | None
    """Smallest rotation to any mapping frame within 1 m (None if none is that close)."""
    visible_objects: int
    """Non-structural objects covering >= 0.5% of the image."""


def visible_ids(instance: np.ndarray, structural_ids: set[int]) -> set[int]:
    """Non-structural instances covering at least :data:`MIN_OBJECT_SHARE` of an instance image."""
    ids, counts = np.unique(instance[instance > 0], return_counts=True)
    return {
        int(i) for i, c in zip(ids, counts) if c >= MIN_OBJECT_SHARE * instance.size and int(i) not in structural_ids
    }


def visibility_check(layout: Layout, spec: SceneSpec, renderer: Renderer) -> Callable[[np.ndarray], set[int]]:
    """The non-structural objects visible from a camera pose, on a :data:`CHECK_WIDTH` instance render."""
    structural = {i.id for i in layout.instances if i.structural}
    cw = min(CHECK_WIDTH, spec.width)
    ch = max(8, int(round(cw * spec.height / spec.width)))
    K_check = geometry.intrinsics_from_fov(cw, ch, spec.fov_y)
    return lambda T: visible_ids(renderer.render_instances(T, K_check, cw, ch), structural)


def seen_counts(layout: Layout, spec: SceneSpec, renderer: Renderer, poses: np.ndarray) -> Counter[int]:
    """How many of ``poses`` see each object (the objects a change should touch to be in view)."""
    check = visibility_check(layout, spec, renderer)
    return Counter(i for T in poses for i in check(T))


def sample_queries(
    layout: Layout, spec: SceneSpec, mapping: np.ndarray, renderer: Renderer, max_tries_per_query: int = 400
) -> tuple[np.ndarray, list[QueryInfo]]:
    """Query poses with a real viewpoint change and enough visible objects (deterministic in the seed)."""
    rng = np.random.default_rng([spec.seed, 13])
    occs = [occupancy_grid(layout, f) for f in range(len(layout.floor_z))]
    cells = [np.argwhere(walkable_region(o) & (o.room_index >= 0)) for o in occs]
    if not any(len(c) for c in cells):
        raise RuntimeError("no free space for query poses")
    weights = np.array([len(c) for c in cells], float)
    boxes = np.array([i.aabb for i in layout.instances if not i.structural]).reshape(-1, 2, 3)
    visible = visibility_check(layout, spec, renderer)
    centres = mapping[:, :3, 3]
    poses, infos = [], []
    tries = 0
    while len(poses) < spec.n_query:
        tries += 1
        if tries > max_tries_per_query * spec.n_query:
            raise RuntimeError(
                f"could only place {len(poses)} of {spec.n_query} query poses "
                "(lower query_min_distance / query_min_angle / query_min_objects)"
            )
        f = int(rng.choice(len(occs), p=weights / weights.sum()))
        r, c = cells[f][int(rng.integers(len(cells[f])))]
        xy = occs[f].centre(np.array([r]), np.array([c]))[0] + rng.uniform(-0.5, 0.5, 2) * GRID_RES
        eye = np.r_[xy, layout.floor_z[f] + rng.uniform(*QUERY_HEIGHT)]
        T = _pose(eye, rng.uniform(-np.pi, np.pi), np.radians(rng.uniform(-40, 15)), np.radians(rng.uniform(-8, 8)))
        if len(boxes) and np.any(np.all((eye > boxes[:, 0] - 0.1) & (eye < boxes[:, 1] + 0.1), axis=1)):
            continue
        d = np.linalg.norm(centres - eye, axis=1)
        near = int(np.argmin(d))
        if d[near] < spec.query_min_distance:
            continue
        ang = geometry.rotation_error(mapping, T)
        within = d <= 1.0
        min_ang = float(ang[within].min()) if within.any() else float("inf")
        if min_ang < spec.query_min_angle:
            continue
        n_vis = len(visible(T))
        if n_vis < spec.query_min_objects:
            continue
        poses.append(T)
        infos.append(
            QueryInfo(
                near,
                round(float(d[near]), 4),
                round(float(ang[near]), 3),
                round(min_ang, 3) if np.isfinite(min_ang) else None,
                n_vis,
            )
        )
    return np.array(poses).reshape(-1, 4, 4), infos


def sample_near_queries(
    layout: Layout, spec: SceneSpec, path: np.ndarray, frames: np.ndarray, renderer: Renderer
) -> np.ndarray:
    """``query_near`` poses: poses of the mapping camera's path between two consecutive mapping frames
    (30-70% of the way), as when query and mapping frames interleave in one video (the paper's ScanNet
    protocol). A random pose of the gap is kept if ``query_min_objects`` objects are visible; every gap
    gives one before any gives two, so queries spread along the path. Deterministic in the seed."""
    rng = np.random.default_rng([spec.seed, 19])
    step = np.r_[np.linalg.norm(np.diff(path[:, :3, 3], axis=0), axis=1), np.inf]
    visible = visibility_check(layout, spec, renderer)
    chosen: set[int] = set()
    for _ in range(NEAR_QUERY_ROUNDS):  # each round takes at most one more pose from every gap
        for k in rng.permutation(len(frames) - 1):
            a, b = int(frames[k]), int(frames[k + 1])
            if step[a:b].max() > GRID_RES:  # a jump between floors, not a walk
                continue
            window = np.arange(max(a + 1, int(np.ceil(a + 0.3 * (b - a)))), min(b, int(a + 0.7 * (b - a)) + 1))
            for j in (int(j) for j in rng.permutation(window) if int(j) not in chosen):
                if len(visible(path[j])) >= spec.query_min_objects:
                    chosen.add(j)
                    break
            if len(chosen) == spec.n_query:
                return path[sorted(chosen)]
    raise RuntimeError(
        f"could only place {len(chosen)} of {spec.n_query} query_near poses along the mapping path "
        "(lower n_query or query_min_objects, or raise max_mapping_frames)"
    )
