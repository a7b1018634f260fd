"""Furniture: beds, seating, tables, storage. Front faces +y, back at min y."""

from __future__ import annotations

import numpy as np
import trimesh

from generators.asset_library.core import Ctx, box, category, cyl, ellipsoid, ring_positions, rod, rotated, torus

WOOD_COLOURS = ("light brown", "brown", "dark brown", "tan", "white", "black", "grey")
FABRIC_COLOURS = (
    "grey",
    "dark grey",
    "blue",
    "navy",
    "beige",
    "green",
    "red",
    "brown",
    "cream",
    "teal",
    "pink",
    "yellow",
    "black",
    "light grey",
    "purple",
    "olive",
    "orange",
)
LEG_COLOURS = ("dark brown", "black", "silver", "light brown")


def _legs(
    ctx: Ctx,
    xy: np.ndarray,
    h: float,
    r: float,
    material: str | None = None,
    colour: str | None = None,
    z: float = 0.0,
    square: bool = False,
) -> None:
    for x, y in xy:
        ctx.add(box(2 * r, 2 * r, h, x, y, z) if square else cyl(r, h, x, y, z, sections=10), material, colour)


def _corners(w: float, d: float, inset: float) -> np.ndarray:
    return np.array([[sx * (w / 2 - inset), sy * (d / 2 - inset)] for sx in (-1, 1) for sy in (-1, 1)])


def _knob(ctx: Ctx, x: float, y: float, z: float, colour: str = "silver") -> None:
    ctx.add(rod((x, y, z), (x, y + 0.025, z), 0.012, sections=8), "metal", colour)


def _bar_handle(ctx: Ctx, x: float, y: float, z0: float, z1: float, colour: str = "silver") -> None:
    ctx.add(rod((x, y + 0.03, z0), (x, y + 0.03, z1), 0.008), "metal", colour)
    ctx.add(rod((x, y, z0), (x, y + 0.03, z0), 0.006), "metal", colour)
    ctx.add(rod((x, y, z1), (x, y + 0.03, z1), 0.006), "metal", colour)


@category(
    "bed",
    "wall",
    ["bedroom"],
    3.0,
    materials=["wood", "wood", "fabric", "metal"],
    colours=WOOD_COLOURS,
    styles=["platform", "classic", "upholstered"],
)
def bed(ctx: Ctx) -> None:
    w = {"small": 0.95, "medium": 1.45, "large": 1.85}[ctx.size] * ctx.u(0.97, 1.04)
    L, frame_h = ctx.u(2.0, 2.15), ctx.u(0.22, 0.35)
    head_h = ctx.u(0.45, 0.75) + (0.2 if ctx.style == "upholstered" else 0.0)
    legs = ctx.style == "classic"
    base_z = 0.12 if legs else 0.0
    if legs:
        _legs(ctx, _corners(w, L, 0.05), base_z + 0.01, 0.035, square=True)
        ctx.add(box(w + 0.04, 0.05, 0.35, 0, L / 2 - 0.025, 0))  # footboard
        ctx.feature("a footboard")
    ctx.add(box(w + 0.04, L, frame_h, 0, 0, base_z))
    ctx.add(box(w + 0.06, 0.08, base_z + frame_h + head_h, 0, -L / 2 - 0.04, 0))
    if ctx.style == "upholstered":
        ctx.add(box(w - 0.1, 0.05, head_h - 0.1, 0, -L / 2 + 0.02, base_z + frame_h + 0.2), "fabric")
        ctx.feature("a padded headboard")
    top = base_z + frame_h
    ctx.add(box(w - 0.04, L - 0.08, 0.2, 0, 0, top), "fabric", "white")
    duvet = ctx.pick(("blue", "grey", "white", "beige", "green", "pink", "navy", "red", "yellow", "teal"))
    ctx.add(box(w + 0.02, L * 0.68, 0.23, 0, L * 0.15, top + 0.01), "fabric", duvet)
    ctx.feature(f"a {duvet} duvet")
    n_pillows = 1 if w < 1.2 else 2
    for x in np.linspace(-w / 4, w / 4, n_pillows) if n_pillows > 1 else [0.0]:
        ctx.add(ellipsoid(min(0.3, w / 2 - 0.12), 0.17, 0.07, x, -L / 2 + 0.28, top + 0.24), "fabric", "white")
    ctx.feature("two pillows" if n_pillows == 2 else "a pillow")


@category(
    "sofa",
    "wall",
    ["living"],
    3.0,
    materials=["fabric", "fabric", "leather"],
    colours=FABRIC_COLOURS,
    styles=["two-seater", "three-seater", "modern"],
)
def sofa(ctx: Ctx) -> None:
    seats = 2 if ctx.style == "two-seater" else 3
    arm_w = ctx.u(0.12, 0.25)
    seat_w = ctx.u(0.55, 0.65) * ctx.s
    w, d = seats * seat_w + 2 * arm_w, ctx.u(0.85, 0.98)
    leg_h = 0.14 if ctx.style == "modern" else 0.05
    seat_z = leg_h + ctx.u(0.2, 0.26)
    _legs(ctx, _corners(w, d, 0.06), leg_h, 0.025, "wood", ctx.pick(LEG_COLOURS))
    ctx.add(box(w, d, seat_z - leg_h, 0, 0, leg_h))
    back_h = ctx.u(0.4, 0.5)
    ctx.add(box(w, 0.2, back_h + seat_z - leg_h, 0, -d / 2 + 0.1, leg_h))
    arm_h = ctx.u(0.18, 0.28)
    for sx in (-1, 1):
        ctx.add(box(arm_w, d, seat_z - leg_h + arm_h, sx * (w - arm_w) / 2, 0, leg_h))
    for i in range(seats):
        x = -w / 2 + arm_w + seat_w * (i + 0.5)
        ctx.add(box(seat_w - 0.02, d - 0.24, 0.14, x, 0.1, seat_z))
        ctx.add(box(seat_w - 0.04, 0.14, back_h - 0.08, x, -d / 2 + 0.26, seat_z + 0.1))
    ctx.feature(f"{'two' if seats == 2 else 'three'} seat cushions")
    if ctx.chance(0.5):
        c = ctx.pick(("yellow", "white", "orange", "teal", "red", "cream"))
        ctx.add(box(0.4, 0.14, 0.4, -w / 2 + arm_w + 0.25, -d / 2 + 0.38, seat_z + 0.14), "fabric", c)
        ctx.feature(f"a {c} cushion")


@category(
    "armchair",
    "floor",
    ["living", "bedroom", "office"],
    2.5,
    materials=["fabric", "fabric", "leather"],
    colours=FABRIC_COLOURS,
    styles=["club", "wingback", "modern"],
)
def armchair(ctx: Ctx) -> None:
    w, d = ctx.u(0.72, 0.9) * ctx.s, ctx.u(0.75, 0.88) * ctx.s
    leg_h = 0.15 if ctx.style == "modern" else 0.05
    seat_z = leg_h + ctx.u(0.25, 0.3)
    arm_w = 0.08 if ctx.style == "modern" else ctx.u(0.14, 0.2)
    back_h = ctx.u(0.45, 0.55) + (0.3 if ctx.style == "wingback" else 0)
    legc = ctx.pick(LEG_COLOURS)
    if ctx.style == "modern":
        for x, y in _corners(w, d, 0.07):
            ctx.add(rod((x, y, leg_h), (x * 1.1, y * 1.1, 0), 0.02), "wood", legc)
        ctx.feature("slim wooden legs")
    else:
        _legs(ctx, _corners(w, d, 0.06), leg_h, 0.025, "wood", legc)
    ctx.add(box(w, d, seat_z - leg_h, 0, 0, leg_h))
    ctx.add(box(w, 0.18, seat_z - leg_h + back_h, 0, -d / 2 + 0.09, leg_h))
    arm_h = ctx.u(0.18, 0.25)
    for sx in (-1, 1):
        ctx.add(box(arm_w, d, seat_z - leg_h + arm_h, sx * (w - arm_w) / 2, 0, leg_h))
        if ctx.style == "wingback":
            ctx.add(box(0.06, 0.25, back_h - 0.1, sx * (w / 2 - 0.03), -d / 2 + 0.3, seat_z + arm_h))
    ctx.add(box(w - 2 * arm_w - 0.02, d - 0.22, 0.13, 0, 0.1, seat_z))
    if ctx.style == "wingback":
        ctx.feature("high wings")


def _table(
    ctx: Ctx,
    w: float,
    d: float,
    h: float,
    round_top: bool,
    top_material: str | None = None,
    top_colour: str | None = None,
) -> None:
    t = ctx.u(0.025, 0.05)
    if round_top:
        ctx.add(cyl(w / 2, t, 0, 0, h - t, sections=24), top_material, top_colour)
    else:
        ctx.add(box(w, d, t, 0, 0, h - t), top_material, top_colour)
    ctx.surface_heights.append(h)


@category(
    "dining_table",
    "floor",
    ["dining", "kitchen"],
    2.5,
    materials=["wood", "wood", "stone", "glass"],
    colours=WOOD_COLOURS,
    styles=["rectangular", "round", "trestle"],
)
def dining_table(ctx: Ctx) -> None:
    h = ctx.u(0.72, 0.77)
    if ctx.style == "round":
        dia = ctx.u(0.9, 1.2) * ctx.s
        _table(ctx, dia, dia, h, True)
        ctx.add(cyl(0.06, h - 0.05, 0, 0, 0.03), "wood", "dark brown")
        ctx.add(cyl(0.3, 0.03), "wood", "dark brown")
        ctx.feature("a central pedestal")
        return
    w, d = ctx.u(1.4, 1.8) * ctx.s, ctx.u(0.8, 0.95) * ctx.s
    _table(ctx, w, d, h, False)
    legc = ctx.pick(("dark brown", "black", "silver", "light brown"))
    if ctx.style == "trestle":
        for sx in (-1, 1):
            ctx.add(box(0.06, d * 0.7, h - 0.04, sx * (w / 2 - 0.2), 0, 0), "wood", legc)
            ctx.add(box(0.1, d * 0.8, 0.05, sx * (w / 2 - 0.2), 0, 0), "wood", legc)
        ctx.add(box(w - 0.4, 0.05, 0.06, 0, 0, 0.2), "wood", legc)
        ctx.feature("trestle legs")
    else:
        _legs(ctx, _corners(w, d, 0.06), h - 0.03, 0.03, "wood", legc, square=True)
        ctx.add(box(w - 0.1, d - 0.1, 0.08, 0, 0, h - 0.11), "wood", legc)
        ctx.feature("four square legs")


@category(
    "coffee_table",
    "floor",
    ["living"],
    2.0,
    materials=["wood", "wood", "glass", "stone"],
    colours=WOOD_COLOURS,
    styles=["rectangular", "round", "glass-top"],
)
def coffee_table(ctx: Ctx) -> None:
    h = ctx.u(0.38, 0.46)
    if ctx.style == "round":
        dia = ctx.u(0.7, 0.9) * ctx.s
        _table(ctx, dia, dia, h, True)
        for x, y in ring_positions(3, dia * 0.33, ctx.u(0, 1)):
            ctx.add(rod((x, y, h - 0.03), (x * 1.25, y * 1.25, 0), 0.02), "wood", "dark brown")
        ctx.feature("three splayed legs")
        return
    w, d = ctx.u(0.9, 1.2) * ctx.s, ctx.u(0.5, 0.65) * ctx.s
    if ctx.style == "glass-top":
        _table(ctx, w, d, h, False, "glass", "light blue")
        for sx in (-1, 1):
            ctx.add(rod((sx * w * 0.45, -d * 0.45, 0.01), (sx * w * 0.45, d * 0.45, 0.01), 0.012), "metal", "silver")
            for sy in (-1, 1):
                ctx.add(
                    rod((sx * w * 0.45, sy * d * 0.45, 0), (sx * w * 0.45, sy * d * 0.45, h - 0.02), 0.012),
                    "metal",
                    "silver",
                )
        ctx.feature("a glass top and a chrome frame")
        return
    _table(ctx, w, d, h, False)
    _legs(ctx, _corners(w, d, 0.05), h - 0.03, 0.025, square=True)
    ctx.add(box(w - 0.08, d - 0.08, 0.025, 0, 0, 0.1))
    ctx.surface_heights.append(0.125)
    ctx.feature("a lower shelf")


@category(
    "side_table",
    "floor",
    ["living", "bedroom"],
    1.5,
    materials=["wood", "metal", "stone"],
    colours=WOOD_COLOURS,
    styles=["round", "square"],
)
def side_table(ctx: Ctx) -> None:
    h, w = ctx.u(0.5, 0.62), ctx.u(0.4, 0.5) * ctx.s
    _table(ctx, w, w, h, ctx.style == "round")
    if ctx.style == "round":
        ctx.add(cyl(0.025, h - 0.02, 0, 0, 0.02), "metal", "black")
        ctx.add(cyl(w * 0.35, 0.02), "metal", "black")
        ctx.feature("a metal pedestal")
    else:
        _legs(ctx, _corners(w, w, 0.03), h - 0.02, 0.018, square=True)
        ctx.add(box(w - 0.04, w - 0.04, 0.12, 0, 0, h - 0.15))
        _knob(ctx, 0, w / 2 - 0.02, h - 0.09)
        ctx.feature("a small drawer")


@category(
    "desk",
    "wall",
    ["office", "bedroom"],
    2.0,
    materials=["wood", "wood", "metal"],
    colours=WOOD_COLOURS,
    styles=["pedestal", "simple", "l-frame"],
)
def desk(ctx: Ctx) -> None:
    w, d, h = ctx.u(1.1, 1.5) * ctx.s, ctx.u(0.6, 0.75), ctx.u(0.72, 0.76)
    _table(ctx, w, d, h, False)
    if ctx.style == "pedestal":
        pw = 0.42
        ctx.add(box(pw, d - 0.04, h - 0.03, w / 2 - pw / 2 - 0.01, 0, 0))
        for k in range(3):
            z = 0.08 + k * (h - 0.15) / 3
            ctx.add(
                box(pw - 0.04, 0.02, (h - 0.15) / 3 - 0.02, w / 2 - pw / 2 - 0.01, d / 2 - 0.02, z),
                "wood",
                "grey" if ctx.colour != "grey" else "white",
            )
            _knob(ctx, w / 2 - pw / 2 - 0.01, d / 2, z + (h - 0.15) / 6)
        ctx.add(box(0.04, d - 0.06, h - 0.03, -w / 2 + 0.03, 0, 0))
        ctx.feature("a set of drawers")
    elif ctx.style == "l-frame":
        for sx in (-1, 1):
            ctx.add(box(0.05, d - 0.1, 0.04, sx * (w / 2 - 0.06), 0, 0), "metal", "black")
            ctx.add(box(0.05, 0.05, h - 0.03, sx * (w / 2 - 0.06), -d / 2 + 0.1, 0), "metal", "black")
            ctx.add(
                rod((sx * (w / 2 - 0.06), -d / 2 + 0.1, 0.02), (sx * (w / 2 - 0.06), d / 2 - 0.06, h - 0.05), 0.02),
                "metal",
                "black",
            )
        ctx.feature("a black steel frame")
    else:
        _legs(ctx, _corners(w, d, 0.04), h - 0.03, 0.022, square=True)
        ctx.add(box(w - 0.1, 0.02, 0.1, 0, d / 2 - 0.06, h - 0.13))


@category(
    "office_chair",
    "floor",
    ["office"],
    2.0,
    materials=["fabric", "leather", "plastic"],
    colours=("black", "dark grey", "grey", "blue", "red", "navy", "white"),
    styles=["task", "executive", "mesh"],
)
def office_chair(ctx: Ctx) -> None:
    leg_r = ctx.u(0.28, 0.33)
    for x, y in ring_positions(5, leg_r, ctx.u(0, np.pi)):
        ctx.add(rod((0, 0, 0.09), (x, y, 0.06), 0.02), "plastic", "black")
        ctx.add(ellipsoid(0.03, 0.03, 0.03, x, y, 0.03, count=8), "plastic", "black")
    seat_z = ctx.u(0.44, 0.52)
    ctx.add(cyl(0.03, seat_z - 0.1, 0, 0, 0.08), "metal", "silver")
    sw = ctx.u(0.46, 0.54) * ctx.s
    ctx.add(box(sw, sw, 0.08, 0, 0.02, seat_z - 0.06))
    back_h = ctx.u(0.45, 0.55) + (0.2 if ctx.style == "executive" else 0)
    ctx.add(rod((0, -sw / 2 + 0.05, seat_z - 0.04), (0, -sw / 2 - 0.04, seat_z + 0.15), 0.02), "metal", "black")
    back_mat = "fabric" if ctx.style == "mesh" else None
    ctx.add(
        rotated_back(sw - 0.04, back_h, -sw / 2 - 0.04, seat_z + 0.1),
        back_mat,
        "black" if ctx.style == "mesh" else None,
    )
    if ctx.style == "executive":
        ctx.add(box(sw * 0.6, 0.06, 0.16, 0, -sw / 2 - 0.07, seat_z + back_h - 0.05))
        ctx.feature("a headrest")
    if ctx.chance(0.7):
        for sx in (-1, 1):
            x = sx * (sw / 2 + 0.02)
            ctx.add(rod((x, 0, seat_z - 0.03), (x, 0, seat_z + 0.2), 0.015), "plastic", "black")
            ctx.add(box(0.06, 0.26, 0.03, x, 0.0, seat_z + 0.2), "plastic", "black")
        ctx.feature("armrests")
    ctx.feature("a five-star base on casters")


def rotated_back(w: float, h: float, y: float, z: float, thick: float = 0.06, tilt: float = 0.1) -> trimesh.Trimesh:
    """Backrest panel tilted backwards by ``tilt`` radians about its bottom edge."""
    return rotated(box(w, thick, h, 0, y, z), tilt, (1, 0, 0), (0, y, z))


@category(
    "dining_chair",
    "floor",
    ["dining", "kitchen"],
    3.0,
    materials=["wood", "wood", "metal", "plastic"],
    colours=WOOD_COLOURS + ("red", "blue", "green", "yellow"),
    styles=["slatted", "solid-back", "upholstered"],
)
def dining_chair(ctx: Ctx) -> None:
    w, d = ctx.u(0.42, 0.48) * ctx.s, ctx.u(0.42, 0.5)
    seat_z, back_h = ctx.u(0.44, 0.48), ctx.u(0.4, 0.5)
    _legs(ctx, _corners(w, d, 0.025), seat_z - 0.03, 0.018, square=ctx.material == "wood")
    for sx in (-1, 1):
        ctx.add(box(0.035, 0.035, back_h + 0.03, sx * (w / 2 - 0.025), -d / 2 + 0.025, seat_z - 0.03))
    ctx.add(box(w, d, 0.04, 0, 0, seat_z - 0.04))
    if ctx.style == "slatted":
        for x in np.linspace(-w / 2 + 0.1, w / 2 - 0.1, 4):
            ctx.add(box(0.025, 0.015, back_h - 0.1, x, -d / 2 + 0.02, seat_z + 0.03))
        ctx.add(box(w - 0.04, 0.03, 0.07, 0, -d / 2 + 0.02, seat_z + back_h - 0.07))
        ctx.feature("a slatted back")
    elif ctx.style == "solid-back":
        ctx.add(box(w - 0.04, 0.025, back_h * 0.55, 0, -d / 2 + 0.02, seat_z + back_h * 0.45))
    else:
        c = ctx.pick(("beige", "grey", "dark red", "navy", "cream", "green"))
        ctx.add(box(w - 0.02, d - 0.02, 0.05, 0, 0.005, seat_z), "fabric", c)
        ctx.add(box(w - 0.06, 0.05, back_h * 0.6, 0, -d / 2 + 0.04, seat_z + back_h * 0.35), "fabric", c)
        ctx.feature(f"a {c} padded seat")


@category(
    "stool",
    "floor",
    ["kitchen", "dining", "office"],
    1.2,
    materials=["wood", "metal", "plastic"],
    colours=WOOD_COLOURS + ("red", "black", "silver"),
    styles=["bar", "low"],
)
def stool(ctx: Ctx) -> None:
    h = ctx.u(0.68, 0.78) if ctx.style == "bar" else ctx.u(0.42, 0.48)
    r = ctx.u(0.16, 0.2) * ctx.s
    ctx.add(cyl(r, 0.04, 0, 0, h - 0.04, sections=20))
    n = ctx.pick((3, 4))
    legs = ring_positions(n, r * 0.7, np.pi / 4)
    for x, y in legs:
        ctx.add(rod((x, y, h - 0.04), (x * 1.35, y * 1.35, 0), 0.015))
    if ctx.style == "bar":
        ctx.add(torus(r * 0.7 * 1.22, 0.01, (0, 0, 0.25)), "metal", "silver")
        ctx.feature("a footrest ring")
    ctx.feature(f"{'three' if n == 3 else 'four'} legs")


@category(
    "bench",
    "floor",
    ["corridor", "dining", "bedroom"],
    0.8,
    materials=["wood", "wood", "metal"],
    colours=WOOD_COLOURS,
    styles=["plain", "backed", "storage"],
)
def bench(ctx: Ctx) -> None:
    w, d, h = ctx.u(1.0, 1.5) * ctx.s, ctx.u(0.35, 0.45), ctx.u(0.43, 0.48)
    ctx.add(box(w, d, 0.05, 0, 0, h - 0.05))
    if ctx.style == "storage":
        ctx.add(box(w - 0.04, d - 0.04, h - 0.05, 0, 0, 0))
        ctx.feature("a storage compartment")
    else:
        for sx in (-1, 1):
            ctx.add(box(0.05, d - 0.04, h - 0.05, sx * (w / 2 - 0.08), 0, 0))
    if ctx.style == "backed":
        for sx in (-1, 1):
            ctx.add(box(0.05, 0.05, 0.45, sx * (w / 2 - 0.08), -d / 2 + 0.03, h))
        ctx.add(box(w - 0.08, 0.03, 0.18, 0, -d / 2 + 0.03, h + 0.25))
        ctx.feature("a backrest")


@category(
    "wardrobe",
    "wall",
    ["bedroom", "corridor"],
    1.5,
    materials=["wood"],
    colours=WOOD_COLOURS,
    styles=["two-door", "three-door", "mirrored"],
)
def wardrobe(ctx: Ctx) -> None:
    n = 3 if ctx.style == "three-door" else 2
    w, d, h = n * ctx.u(0.45, 0.55) * ctx.s, ctx.u(0.55, 0.62), ctx.u(1.9, 2.2)
    ctx.add(box(w, d, h - 0.08, 0, 0, 0.08))
    ctx.add(box(w - 0.04, d - 0.04, 0.08), "wood", "dark brown")
    dw = (w - 0.02) / n
    for i in range(n):
        x = -w / 2 + 0.01 + dw * (i + 0.5)
        if ctx.style == "mirrored" and i == 0:
            ctx.add(box(dw - 0.1, 0.012, h - 0.5, x, d / 2, 0.3), "glass", "light blue")
            ctx.feature("a mirrored door")
        ctx.add(box(dw - 0.01, 0.02, h - 0.12, x, d / 2 - 0.01, 0.1))
        hx = x + (dw / 2 - 0.06) * (1 if i % 2 == 0 else -1)
        _bar_handle(ctx, hx, d / 2 + 0.01, h * 0.45, h * 0.58)
    ctx.feature(f"{'three' if n == 3 else 'two'} tall doors")
    ctx.surface_heights.append(h)


@category("dresser", "wall", ["bedroom"], 1.2, materials=["wood"], colours=WOOD_COLOURS, styles=["wide", "tall"])
def dresser(ctx: Ctx) -> None:
    cols = 2 if ctx.style == "wide" else 1
    rows = 3 if ctx.style == "wide" else 5
    w, d = cols * ctx.u(0.45, 0.6) * ctx.s, ctx.u(0.42, 0.5)
    h = rows * ctx.u(0.2, 0.24) + 0.12
    leg_c = ctx.pick(LEG_COLOURS)
    _legs(ctx, _corners(w, d, 0.04), 0.1, 0.02, "wood", leg_c)
    ctx.add(box(w, d, h - 0.1, 0, 0, 0.1))
    dh = (h - 0.14) / rows
    front = ctx.pick(("white", "cream", "grey", "light brown", ctx.colour))
    for r in range(rows):
        for c in range(cols):
            x = -w / 2 + w / cols * (c + 0.5)
            z = 0.11 + r * dh
            ctx.add(box(w / cols - 0.02, 0.02, dh - 0.02, x, d / 2, z + 0.01), "wood", front)
            _knob(ctx, x, d / 2 + 0.02, z + dh / 2)
    ctx.feature(f"{rows * cols} drawers")
    ctx.surface_heights.append(h)


BOOK_COLOURS = ("red", "blue", "green", "yellow", "white", "navy", "dark red", "orange", "black", "teal")


def book_row(
    ctx: Ctx, x0: float, x1: float, z: float, y: float, depth: float, max_h: float, palette: tuple[str, ...]
) -> None:
    """Books standing side by side from x0 towards x1 on a shelf at height z (a random share of it).

    ``palette`` is a few colours per piece of furniture: each colour is one renderer geom.
    """
    x = x0
    end = x0 + (x1 - x0) * ctx.u(0.4, 0.95)
    while x < end:
        t = ctx.u(0.02, 0.05)
        bh = min(max_h, ctx.u(0.18, 0.3))
        ctx.add(box(t, depth * ctx.u(0.6, 0.85), bh, x + t / 2, y, z), "paper", ctx.pick(palette))
        x += t + 0.003


@category(
    "bookshelf",
    "wall",
    ["living", "office", "bedroom"],
    2.0,
    materials=["wood", "wood", "metal"],
    colours=WOOD_COLOURS,
    styles=["tall", "low", "ladder"],
)
def bookshelf(ctx: Ctx) -> None:
    w, d = ctx.u(0.6, 1.0) * ctx.s, ctx.u(0.28, 0.36)
    n = ctx.pick((4, 5)) if ctx.style != "low" else 2
    h = ctx.u(0.33, 0.38) * n + 0.05
    t = 0.02
    ctx.add(box(w, 0.01, h, 0, -d / 2 + 0.005, 0))
    for sx in (-1, 1):
        ctx.add(box(t, d, h, sx * (w / 2 - t / 2), 0, 0))
    gap = (h - t) / n
    palette = tuple(str(c) for c in ctx.rng.permutation(BOOK_COLOURS)[:4])
    for i in range(n + 1):
        ctx.add(box(w - 2 * t, d, t, 0, 0, i * gap if i < n else h - t))
    for i in range(n):
        if ctx.chance(0.85):
            book_row(ctx, -w / 2 + t, w / 2 - t, i * gap + t, 0.0, d, gap - 0.04, palette)
    ctx.feature(f"{n} shelves")
    ctx.feature("rows of books")
    ctx.surface_heights.append(h)


@category(
    "cabinet",
    "wall",
    ["kitchen", "living", "dining", "bathroom"],
    1.5,
    materials=["wood", "wood", "metal"],
    colours=WOOD_COLOURS + ("cream", "light grey", "navy", "green"),
    styles=["sideboard", "base", "glass-door"],
)
def cabinet(ctx: Ctx) -> None:
    n = ctx.pick((2, 3, 4)) if ctx.style == "sideboard" else 2
    w, d = n * ctx.u(0.38, 0.45) * ctx.s, ctx.u(0.42, 0.6)
    h = ctx.u(0.75, 0.9) if ctx.style != "glass-door" else ctx.u(1.5, 1.8)
    leg = 0.12 if ctx.style == "sideboard" else 0.0
    if leg:
        _legs(ctx, _corners(w, d, 0.05), leg, 0.02, "metal", "black")
    ctx.add(box(w, d, h - leg, 0, 0, leg))
    dw = w / n
    for i in range(n):
        x = -w / 2 + dw * (i + 0.5)
        if ctx.style == "glass-door":
            ctx.add(box(dw - 0.08, 0.012, h - 0.2, x, d / 2, 0.1), "glass", "light blue")
            for k in range(1, 4):
                ctx.add(box(dw - 0.12, 0.01, 0.015, x, d / 2 - 0.3, k * (h - 0.1) / 4), "glass", "light grey")
        else:
            ctx.add(box(dw - 0.02, 0.02, h - leg - 0.04, x, d / 2, leg + 0.02))
        _bar_handle(
            ctx, x + (dw / 2 - 0.05) * (1 if i % 2 else -1), d / 2 + 0.01, leg + (h - leg) * 0.55, leg + (h - leg) * 0.7
        )
    ctx.feature("glass doors" if ctx.style == "glass-door" else f"{n} doors")
    ctx.surface_heights.append(h)


@category(
    "nightstand", "floor", ["bedroom"], 2.0, materials=["wood"], colours=WOOD_COLOURS, styles=["drawer", "open-shelf"]
)
def nightstand(ctx: Ctx) -> None:
    w, d, h = ctx.u(0.4, 0.55) * ctx.s, ctx.u(0.35, 0.42), ctx.u(0.48, 0.6)
    _legs(ctx, _corners(w, d, 0.03), 0.12, 0.015, "wood", ctx.pick(LEG_COLOURS))
    ctx.add(box(w, d, 0.03, 0, 0, 0.12))
    ctx.add(box(w, d, 0.03, 0, 0, h - 0.03))
    for sx in (-1, 1):
        ctx.add(box(0.02, d, h - 0.15, sx * (w / 2 - 0.01), 0, 0.12))
    ctx.add(box(w, 0.01, h - 0.15, 0, -d / 2 + 0.005, 0.12))
    if ctx.style == "drawer":
        ctx.add(box(w - 0.04, d - 0.02, (h - 0.15) / 2, 0, 0.01, h - 0.03 - (h - 0.15) / 2))
        _knob(ctx, 0, d / 2 + 0.01, h - 0.03 - (h - 0.15) / 4)
        ctx.feature("a drawer")
    else:
        ctx.feature("an open shelf")
    ctx.surface_heights.append(h)


@category(
    "tv_stand",
    "wall",
    ["living"],
    1.2,
    materials=["wood", "wood", "metal"],
    colours=WOOD_COLOURS,
    styles=["open", "closed"],
)
def tv_stand(ctx: Ctx) -> None:
    w, d, h = ctx.u(1.2, 1.8) * ctx.s, ctx.u(0.38, 0.45), ctx.u(0.42, 0.55)
    _legs(ctx, _corners(w, d, 0.04), 0.08, 0.02, "metal", "black")
    ctx.add(box(w, d, 0.025, 0, 0, 0.08))
    ctx.add(box(w, d, 0.03, 0, 0, h - 0.03))
    n = 3
    for i in range(n + 1):
        ctx.add(box(0.025, d, h - 0.13, -w / 2 + 0.0125 + i * (w - 0.025) / n, 0, 0.105))
    ctx.add(box(w, 0.01, h - 0.13, 0, -d / 2 + 0.005, 0.105))
    if ctx.style == "closed":
        for i in (0, 2):
            x = -w / 2 + (w / n) * (i + 0.5)
            ctx.add(box(w / n - 0.03, 0.02, h - 0.15, x, d / 2 - 0.01, 0.115))
            _knob(ctx, x, d / 2, h / 2 + 0.05)
        ctx.feature("two cupboard doors")
    else:
        ctx.feature("open compartments")
    ctx.surface_heights.append(h)


@category(
    "shoe_rack", "wall", ["corridor", "bedroom"], 0.5, materials=["wood", "metal"], colours=WOOD_COLOURS + ("silver",)
)
def shoe_rack(ctx: Ctx) -> None:
    w, d, h = ctx.u(0.6, 0.9) * ctx.s, ctx.u(0.28, 0.33), ctx.u(0.45, 0.6)
    for sx in (-1, 1):
        ctx.add(box(0.025, d, h, sx * (w / 2 - 0.0125), 0, 0))
    for k in range(3):
        z = 0.05 + k * (h - 0.08) / 2
        for y in (-d / 4, d / 4):
            ctx.add(rod((-w / 2 + 0.02, y, z), (w / 2 - 0.02, y, z + 0.0), 0.01))
        if k < 2:
            for x in np.linspace(-w / 2 + 0.1, w / 2 - 0.1, int(w / 0.18)):
                c = ctx.pick(("black", "brown", "white", "navy", "red"))
                ctx.add(box(0.09, 0.25, 0.08, x, 0, z + 0.01), "leather", c)
    ctx.add(box(w, d, 0.02, 0, 0, h - 0.02))
    ctx.feature("pairs of shoes")
    ctx.surface_heights.append(h)


@category(
    "coat_rack",
    "floor",
    ["corridor", "bedroom"],
    0.5,
    materials=["wood", "metal"],
    colours=("dark brown", "black", "light brown", "white", "silver"),
)
def coat_rack(ctx: Ctx) -> None:
    h = ctx.u(1.65, 1.85) * ctx.s**0.3
    for x, y in ring_positions(3, 0.25, ctx.u(0, 2)):
        ctx.add(rod((0, 0, 0.15), (x, y, 0.0), 0.015))
    ctx.add(cyl(0.022, h, 0, 0, 0))
    for x, y in ring_positions(4, 0.13, 0.3):
        ctx.add(rod((0, 0, h - 0.2), (x, y, h - 0.1), 0.01))
    if ctx.chance(0.7):
        c = ctx.pick(("navy", "beige", "red", "dark grey", "olive", "brown"))
        ctx.add(ellipsoid(0.2, 0.1, 0.42, 0.12, 0.0, h - 0.52), "fabric", c)
        ctx.feature(f"a {c} coat hanging on it")
    ctx.feature("hooks at the top")
