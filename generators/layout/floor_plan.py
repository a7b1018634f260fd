"""Floor plans: the rooms of every storey, where the stairs go up and which walls get a doorway.

A storey is two strips of rooms (with a corridor between them when it has 5+ rooms) on a rectangular
footprint that every storey shares. Cells are in wall-centre coordinates; a room is its cell less half a
wall (:data:`~generators.layout.model.WALL_T`) on every side. Doorways connect every room to the rest (a
spanning tree of the adjacency graph plus a few loops). A straight stair run stands against an outer wall
of a stair room whose x-range is the same on the two storeys it joins.
"""

from __future__ import annotations

from dataclasses import dataclass

import networkx as nx
import numpy as np

from generators.layout.model import DOOR_W, WALL_T, Door, Room
from generators.spec import SceneSpec

CORRIDOR_W = 1.6
STAIR_LEN, STAIR_W = 4.0, 1.0
ROOM_KINDS_NO_CORRIDOR = ("bedroom", "kitchen", "living", "office", "bathroom", "dining")


@dataclass
class FloorPlan:
    """Cells of one floor in wall-centre coordinates, and the kind of room each holds."""

    cells: list[tuple[float, float, float, float]]
    kinds: list[str]


def _split_length(total: float, n: int, lo: float, rng: np.random.Generator) -> list[float]:
    w = lo + (total - n * lo) * rng.dirichlet(np.full(n, 4.0))
    return list(w)


def footprint_strips(spec: SceneSpec, rng: np.random.Generator) -> dict:
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


def floor_plan(spec: SceneSpec, shape: dict, counts: tuple[int, int], rng: np.random.Generator) -> FloorPlan:
    """The cells of one storey on the footprint ``shape`` of :func:`footprint_strips`."""
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
    return FloorPlan(cells, kinds)


def shared_edge(a: tuple, b: tuple, min_len: float) -> tuple[int, float, float, float] | None:
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


def rooms_of(plan: FloorPlan, f: int, spec: SceneSpec, z0: float) -> list[Room]:
    """The rooms of floor ``f``'s cells, named by kind (``f1_kitchen_2`` in a multi-floor scene)."""
    h = WALL_T / 2
    rooms = []
    counters: dict[str, int] = {}
    for cell, kind in zip(plan.cells, plan.kinds):
        counters[kind] = counters.get(kind, 0) + 1
        name = f"f{f}_{kind}_{counters[kind]}" if spec.floors > 1 else f"{kind}_{counters[kind]}"
        rooms.append(Room(name, kind, f, (cell[0] + h, cell[1] + h, cell[2] - h, cell[3] - h), z0, spec.ceiling_height))
    return rooms


def stair_up(f: int, plan: FloorPlan, rooms: list[Room], footprint: tuple[float, float]) -> tuple[int, tuple]:
    """(room index, rect) of the stair run up from floor ``f``: against the outer wall of the first cell of
    the top strip (even floors, or floors without a bottom strip) or of the bottom strip."""
    top = f % 2 == 0 or not any(cell[1] == 0.0 for cell in plan.cells)
    idx = next(
        i
        for i, cell in enumerate(plan.cells)
        if (cell[3] == footprint[1] if top else cell[1] == 0.0) and plan.kinds[i] != "corridor"
    )
    r = rooms[idx].rect
    sx0 = r[0] + 0.3
    rect = (sx0, r[3] - STAIR_W, sx0 + STAIR_LEN, r[3]) if top else (sx0, r[1], sx0 + STAIR_LEN, r[1] + STAIR_W)
    return idx, rect


def doorways(
    f: int, plan: FloorPlan, rooms: list[Room], z0: float, stair_rects: list[tuple], rng: np.random.Generator
) -> tuple[list[Door], list[tuple[int, float, float, float]]]:
    """The doors of floor ``f`` and their openings in the walls, (axis, fixed, lo, hi) each: a spanning
    tree of the adjacency graph (corridor first) plus a few extra loops, kept clear of ``stair_rects``."""
    g = nx.Graph()
    g.add_nodes_from(range(len(rooms)))
    for i in range(len(rooms)):
        for j in range(i + 1, len(rooms)):
            e = shared_edge(plan.cells[i], plan.cells[j], DOOR_W + 0.8)
            if e is not None:
                is_corr = "corridor" in (plan.kinds[i], plan.kinds[j])
                g.add_edge(i, j, edge=e, weight=float(rng.uniform(0, 1)) - (2.0 if is_corr else 0.0))
    tree = nx.minimum_spanning_tree(g)
    door_edges = set(tree.edges())
    for i, j in sorted(g.edges()):
        if (i, j) not in door_edges and (j, i) not in door_edges and rng.random() < 0.25:
            door_edges.add((i, j))
    doors: list[Door] = []
    openings: list[tuple[int, float, float, float]] = []
    for i, j in sorted(tuple(sorted(e)) for e in door_edges):
        axis, fixed, lo, hi = g.edges[i, j]["edge"]
        for _ in range(20):
            centre = float(rng.uniform(lo + 0.4 + DOOR_W / 2, hi - 0.4 - DOOR_W / 2))
            p = np.array([centre, fixed]) if axis == 0 else np.array([fixed, centre])
            clear = all(not (s[0] - 0.9 < p[0] < s[2] + 0.9 and s[1] - 0.9 < p[1] < s[3] + 0.9) for s in stair_rects)
            if clear:
                break
        openings.append((axis, fixed, centre - DOOR_W / 2, centre + DOOR_W / 2))
        doors.append(Door(f, np.array([p[0], p[1], z0]), axis, (rooms[i].name, rooms[j].name)))
    return doors, openings
