"""A scene's layout from its spec: the floor plan of each storey, its structure, then the furnishing.

Every choice draws from one random stream in a fixed order (storey by storey: wall colours, the railing
round the opening from below, slabs, stairs, doorways, walls with their door frames and windows; then
every room's furniture), so the same spec and seed give the same layout, instance ids included.
"""

from __future__ import annotations

import numpy as np

from generators.layout.floor_plan import (
    CORRIDOR_W,
    FloorPlan,
    doorways,
    floor_plan,
    footprint_strips,
    rooms_of,
    stair_up,
)
from generators.layout.furnish import Furnisher
from generators.layout.model import Layout, LayoutDraft
from generators.layout.structure import add_railing, add_slabs, add_stairs, add_walls, ceiling_lights, wall_colours
from generators.spec import SceneSpec


def build_layout(spec: SceneSpec) -> Layout:
    """Deterministic layout of ``spec`` (same spec and seed -> identical layout)."""
    draft = LayoutDraft(spec)
    shape = footprint_strips(spec, draft.rng)
    counts = shape["counts"]
    depth = shape["d_bot"] + (CORRIDOR_W if shape["corridor"] else 0.0) + shape["d_top"]
    footprint = (shape["L"], depth)
    stair_cells: list[tuple[float, float, float, float]] = []  # stair rect for floor f -> f+1
    for f in range(spec.floors):
        plan = floor_plan(spec, shape, counts, draft.rng)
        _build_floor(draft, f, plan, footprint, stair_cells)
    furnisher = Furnisher(draft)
    for f in range(spec.floors):
        for room in draft.rooms_on(f):
            furnisher.furnish(room)
    draft.finish_surfaces()
    return draft.layout(footprint)


def _build_floor(
    draft: LayoutDraft, f: int, plan: FloorPlan, footprint: tuple[float, float], stair_cells: list
) -> None:
    """Rooms, slabs, stairs, doors, walls and lights of floor ``f``; appends its stair rect (if any) to
    ``stair_cells``, which holds the rects of the floors below."""
    z0 = f * draft.storey
    rooms = rooms_of(plan, f, draft.spec, z0)
    draft.rooms.extend(rooms)
    wall_colour = wall_colours(rooms, draft.rng)
    # stairs: up from this floor (in the first cell of the top / bottom strip), opening from below
    holes_floor: dict[int, list] = {i: [] for i in range(len(rooms))}
    holes_ceiling: dict[int, list] = {i: [] for i in range(len(rooms))}
    stair_rects = []
    stair_here = None
    if f < draft.spec.floors - 1:
        stair_here = stair_up(f, plan, rooms, footprint)
        idx, rect = stair_here
        stair_cells.append(rect)
        stair_rects.append(rect)
        holes_ceiling[idx].append(rect)
    if f > 0:
        below = stair_cells[f - 1]
        stair_rects.append(below)
        for i, room in enumerate(rooms):
            if room.contains_xy(np.array([(below[0] + below[2]) / 2, (below[1] + below[3]) / 2])):
                holes_floor[i].append(below)
                add_railing(draft, room, below, z0)
                draft.blocked.append((f, below))
    add_slabs(draft, plan, rooms, holes_floor, holes_ceiling, z0)
    if stair_here is not None:
        idx, rect = stair_here
        add_stairs(draft, rooms[idx], rect, z0)
        draft.blocked.append((f, rect))
    doors, openings = doorways(f, plan, rooms, z0, stair_rects, draft.rng)
    draft.doors.extend(doors)
    add_walls(draft, f, plan, rooms, wall_colour, openings, z0)
    draft.lights.extend(ceiling_lights(rooms))
