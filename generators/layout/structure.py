"""The building as geometry: floor and ceiling slabs, walls, door frames, windows, stairs, railings and
the ceiling lights, each structural part an :class:`~generators.layout.model.Instance` of its own.

Walls sit on the cell boundaries of the floor plan (centred, :data:`~generators.layout.model.WALL_T`
thick) with holes at the doorways; outer walls get windows; the slab above a stair run has an opening
with a railing. Every colour and texture seed is drawn from the draft's random stream as each part is
made.
"""

from __future__ import annotations

import numpy as np
import trimesh

from generators.layout.floor_plan import STAIR_LEN, FloorPlan
from generators.layout.model import DOOR_H, SLAB_T, WALL_T, LayoutDraft, Light, Room, box_mesh, make_part

_FLOOR_MATERIAL = {
    "bedroom": "wood",
    "living": "wood",
    "office": "wood",
    "dining": "wood",
    "kitchen": "ceramic",
    "bathroom": "ceramic",
    "corridor": "stone",
}
_WALL_COLOURS = ("white", "cream", "beige", "light grey", "light blue", "pink", "light brown", "grey")
_FLOOR_COLOURS = ("light brown", "brown", "tan", "beige", "grey", "dark brown", "white", "cream")


def wall_colours(rooms: list[Room], rng: np.random.Generator) -> dict[str, str]:
    """The colour of each room's walls, by room name."""
    return {r.name: _WALL_COLOURS[int(rng.integers(len(_WALL_COLOURS)))] for r in rooms}


def add_slabs(
    draft: LayoutDraft,
    plan: FloorPlan,
    rooms: list[Room],
    holes_floor: dict[int, list],
    holes_ceiling: dict[int, list],
    z0: float,
) -> None:
    """A floor and a ceiling slab over each room's cell, less the stair openings (by room index)."""
    rng, H = draft.rng, draft.spec.ceiling_height
    for i, (cell, room) in enumerate(zip(plan.cells, rooms)):
        fkind = _FLOOR_MATERIAL[room.kind]
        fcol = _FLOOR_COLOURS[int(rng.integers(len(_FLOOR_COLOURS)))]
        draft.add(
            category="floor",
            parts=[make_part(_slab_with_holes(cell, z0 - SLAB_T, z0, holes_floor[i]), fkind, fcol, draft.tex_seed())],
            transform=np.eye(4),
            structural=True,
            room=room.name,
            floor=room.floor,
            description=f"a {fcol} {fkind} floor",
            attributes={"colour": fcol, "material": fkind},
        )
        draft.add(
            category="ceiling",
            parts=[
                make_part(
                    _slab_with_holes(cell, z0 + H, z0 + H + SLAB_T, holes_ceiling[i]),
                    "plaster",
                    "white",
                    draft.tex_seed(),
                )
            ],
            transform=np.eye(4),
            structural=True,
            room=room.name,
            floor=room.floor,
            description="a white plaster ceiling",
            attributes={"colour": "white", "material": "plaster"},
        )


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


def add_walls(
    draft: LayoutDraft,
    f: int,
    plan: FloorPlan,
    rooms: list[Room],
    wall_colour: dict[str, str],
    openings: list[tuple[int, float, float, float]],
    z0: float,
) -> None:
    """The walls of floor ``f``, with their door frames and windows: every cell edge split at the
    breakpoints of all cells on the same line, a plaster face towards each room (in its colour) and a
    grey one outside, holes at the door ``openings``, a window in most long outer walls."""
    rng, H = draft.rng, draft.spec.ceiling_height
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
                (o[2], o[3]) for o in openings if o[0] == axis and abs(o[1] - fixed) < 1e-6 and a <= o[2] and o[3] <= b
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
                pieces = _wall_pieces(axis, fixed + off[0], fixed + off[1], ea, eb, holes, z0, H)
                surface = "bare" if draft.bare_walls(room.name) else "pattern"
                parts.append(make_part(pieces, "plaster", wall_colour[room.name], draft.tex_seed(), surface))
            outer_side = [k for k in (0, 1) if sides[k] is None]
            for k in outer_side:  # exterior face: plain grey render
                off = (-h, 0.0) if k == 0 else (0.0, h)
                parts.append(
                    make_part(
                        _wall_pieces(axis, fixed + off[0], fixed + off[1], ea, eb, holes, z0, H),
                        "plaster",
                        "light grey",
                        draft.tex_seed(),
                    )
                )
            named = [s.name for s in sides if s is not None]
            draft.add(
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
                _door_frame(draft, axis, fixed, lo, hi, z0, f, named)
            if window is not None:
                inside = 0 if sides[0] is not None else 1
                _window(draft, axis, fixed, window, z0, f, sides[inside], inside)


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


def _door_frame(draft: LayoutDraft, axis, fixed, lo, hi, z0, f, rooms) -> None:
    depth, w = WALL_T + 0.04, 0.06

    def mk(u0, u1, za, zb):
        t0, t1 = fixed - depth / 2, fixed + depth / 2
        return box_mesh((u0, t0, za), (u1, t1, zb)) if axis == 0 else box_mesh((t0, u0, za), (t1, u1, zb))

    meshes = [
        mk(lo, lo + w, z0, z0 + DOOR_H),
        mk(hi - w, hi, z0, z0 + DOOR_H),
        mk(lo, hi, z0 + DOOR_H - w, z0 + DOOR_H),
    ]
    colour = ("white", "brown", "dark brown", "light brown")[int(draft.rng.integers(4))]
    draft.add(
        category="door",
        parts=[make_part(meshes, "wood", colour, draft.tex_seed())],
        transform=np.eye(4),
        structural=True,
        room=rooms[0],
        floor=f,
        description=f"a {colour} wooden door frame",
        attributes={"colour": colour, "material": "wood", "rooms": ",".join(rooms)},
    )


def _window(draft: LayoutDraft, axis, fixed, span, z0, f, room: Room, inside: int) -> None:
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
    draft.add(
        category="window",
        parts=[
            make_part(frame, "plastic", "white", draft.tex_seed()),
            make_part(pane, "glass", "light blue", draft.tex_seed()),
        ],
        transform=np.eye(4),
        structural=True,
        room=room.name,
        floor=f,
        description="a white framed window",
        attributes={"colour": "white", "material": "glass"},
    )


def add_stairs(draft: LayoutDraft, room: Room, rect, z0: float) -> None:
    """A straight run of 16 steps up to the next floor over ``rect``."""
    n = 16
    rise, run = draft.storey / n, STAIR_LEN / n
    x0, y0, x1, y1 = rect
    steps = [box_mesh((x0 + i * run, y0, z0), (x0 + (i + 1) * run, y1, z0 + (i + 1) * rise)) for i in range(n)]
    colour = ("grey", "brown", "light brown")[int(draft.rng.integers(3))]
    draft.add(
        category="stairs",
        parts=[make_part(steps, "wood" if colour != "grey" else "stone", colour, draft.tex_seed())],
        transform=np.eye(4),
        structural=True,
        room=room.name,
        floor=room.floor,
        description=f"a straight {colour} staircase",
        attributes={"colour": colour, "material": "wood"},
    )


def add_railing(draft: LayoutDraft, room: Room, hole, z0: float) -> None:
    """A railing around the stair opening ``hole`` in the floor of ``room``."""
    x0, y0, x1, y1 = hole
    inner_y = y0 if abs(y1 - room.rect[3]) < 1e-6 else y1
    posts = [
        box_mesh((x - 0.02, inner_y - 0.02, z0), (x + 0.02, inner_y + 0.02, z0 + 1.0)) for x in np.linspace(x0, x1, 9)
    ]
    posts.append(box_mesh((x0 - 0.03, inner_y - 0.03, z0 + 0.95), (x1 + 0.03, inner_y + 0.03, z0 + 1.0)))
    ya, yb = sorted((y0, y1))
    posts += [box_mesh((x0 - 0.02, y - 0.02, z0), (x0 + 0.02, y + 0.02, z0 + 1.0)) for y in np.linspace(ya, yb, 4)]
    posts.append(box_mesh((x0 - 0.03, ya, z0 + 0.95), (x0 + 0.03, yb, z0 + 1.0)))
    draft.add(
        category="railing",
        parts=[make_part(posts, "metal", "dark grey", draft.tex_seed())],
        transform=np.eye(4),
        structural=True,
        room=room.name,
        floor=room.floor,
        description="a dark grey metal railing",
        attributes={"colour": "dark grey", "material": "metal"},
    )


def ceiling_lights(rooms: list[Room]) -> list[Light]:
    """One light per room, two along the long axis of big rooms, 0.35 m below the ceiling."""
    lights = []
    for room in rooms:
        x0, y0, x1, y1 = room.rect
        n_l = 2 if room.area > 18 else 1
        long_x = (x1 - x0) >= (y1 - y0)
        for k in range(n_l):
            t = (k + 1) / (n_l + 1)
            pos = (x0 + t * (x1 - x0), (y0 + y1) / 2) if long_x else ((x0 + x1) / 2, y0 + t * (y1 - y0))
            lights.append(Light(np.array([pos[0], pos[1], room.z0 + room.height - 0.35]), room.name, room.floor))
    return lights
