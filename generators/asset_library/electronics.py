"""Electronics and lighting. Front (screens, grilles) faces +y, back at min y."""

from __future__ import annotations

import numpy as np

from generators.asset_library.core import (
    ROOM_KINDS,
    Ctx,
    box,
    category,
    cyl,
    ellipsoid,
    moved,
    revolve,
    ring_positions,
    rod,
    rotated,
    torus,
    vessel,
)

DEVICE_COLOURS = ("black", "black", "dark grey", "silver", "white")
SHADE_COLOURS = ("white", "cream", "beige", "grey", "yellow", "light blue", "green", "black", "orange", "pink")


def _screen(ctx: Ctx, w: float, h: float, thick: float, z: float, y: float = 0.0, bezel: float = 0.015) -> None:
    """Display panel: housing in the main colour and a black glass screen on its front (+y)."""
    ctx.add(box(w, thick, h, 0, y, z))
    ctx.add(box(w - 2 * bezel, 0.004, h - 2 * bezel, 0, y + thick / 2, z + bezel), "glass", "black")


@category(
    "tv",
    "surface",
    ["living", "bedroom"],
    1.5,
    materials=["plastic", "metal"],
    colours=DEVICE_COLOURS,
    styles=["pedestal", "feet"],
    noun="TV",
)
def tv(ctx: Ctx) -> None:
    w = ctx.u(0.95, 1.25) * ctx.s
    h = w * 9 / 16 + 0.03
    foot_h = ctx.u(0.05, 0.09)
    if ctx.style == "pedestal":
        ctx.add(box(w * 0.3, 0.22, 0.015), "metal", "dark grey")
        ctx.add(box(0.06, 0.03, foot_h + 0.1, 0, -0.02, 0.015), "metal", "dark grey")
        ctx.feature("a pedestal stand")
    else:
        for sx in (-1, 1):
            ctx.add(box(0.03, 0.24, 0.012, sx * w * 0.4, 0, 0), "metal", "dark grey")
            ctx.add(box(0.025, 0.025, foot_h + 0.05, sx * w * 0.4, 0, 0.012), "metal", "dark grey")
        ctx.feature("two slim feet")
    _screen(ctx, w, h, 0.045, foot_h + 0.02, 0.0, 0.012)
    ctx.feature("a large black screen")


@category(
    "monitor",
    "surface",
    ["office", "bedroom"],
    1.5,
    materials=["plastic", "metal"],
    colours=DEVICE_COLOURS,
    styles=["column", "arm", "ultrawide"],
)
def monitor(ctx: Ctx) -> None:
    w = ctx.u(0.8, 0.9) if ctx.style == "ultrawide" else ctx.u(0.48, 0.62) * ctx.s
    h = ctx.u(0.34, 0.4) if ctx.style == "ultrawide" else w * 0.6
    z = ctx.u(0.1, 0.16)
    if ctx.style == "arm":
        ctx.add(cyl(0.02, z + h * 0.5 + 0.1, 0, -0.15, 0), "metal", "silver")
        ctx.add(box(0.1, 0.08, 0.04, 0, -0.15, 0), "metal", "silver")
        ctx.add(rod((0, -0.15, z + h * 0.5), (0, -0.03, z + h * 0.5), 0.015), "metal", "silver")
        ctx.feature("a clamp arm")
    else:
        ctx.add(box(0.24, 0.18, 0.015, 0, -0.02, 0))
        ctx.add(box(0.05, 0.025, z + h * 0.4, 0, -0.06, 0.015))
        ctx.feature("a rectangular stand")
    _screen(ctx, w, h, 0.03, z, 0.0, 0.01)
    ctx.add(box(w * 0.25, 0.04, h * 0.3, 0, -0.03, z + h * 0.35))


@category(
    "laptop",
    "surface",
    ["office", "bedroom", "living"],
    1.2,
    materials=["metal", "plastic"],
    colours=("silver", "silver", "dark grey", "black", "white", "gold"),
)
def laptop(ctx: Ctx) -> None:
    w, d = ctx.u(0.3, 0.36) * ctx.s, ctx.u(0.21, 0.25) * ctx.s
    ctx.add(box(w, d, 0.016))
    ctx.add(box(w * 0.9, d * 0.45, 0.002, 0, -d * 0.12, 0.016), "plastic", "black")
    ctx.add(box(w * 0.3, d * 0.22, 0.001, 0, d * 0.3, 0.016), "plastic", "dark grey")
    open_angle = ctx.u(0.2, 0.45)
    lid = box(w, 0.008, d, 0, -d / 2, 0.016)
    scr = box(w * 0.92, 0.002, d * 0.86, 0, -d / 2 + 0.005, 0.016 + d * 0.07)
    ctx.add(rotated(lid, -open_angle, (1, 0, 0), (0, -d / 2, 0.016)))
    ctx.add(rotated(scr, -open_angle, (1, 0, 0), (0, -d / 2, 0.016)), "glass", "black")
    ctx.feature("an open screen")
    ctx.feature("a black keyboard")


@category(
    "radio",
    "surface",
    ["kitchen", "living", "bedroom"],
    0.5,
    materials=["plastic", "wood", "metal"],
    colours=("red", "cream", "black", "silver", "brown", "light blue", "green", "orange"),
)
def radio(ctx: Ctx) -> None:
    w, d, h = ctx.u(0.22, 0.3) * ctx.s, ctx.u(0.08, 0.11), ctx.u(0.13, 0.17) * ctx.s
    ctx.add(box(w, d, h))
    ctx.add(
        rod((-w * 0.18, d / 2 - 0.002, h * 0.5), (-w * 0.18, d / 2 + 0.004, h * 0.5), h * 0.36, sections=20),
        "fabric",
        "dark grey",
    )
    for x in (w * 0.2, w * 0.36):
        ctx.add(rod((x, d / 2, h * 0.35), (x, d / 2 + 0.02, h * 0.35), 0.015, sections=12), "metal", "silver")
    ctx.add(box(w * 0.32, 0.004, h * 0.2, w * 0.28, d / 2, h * 0.62), "glass", "cream")
    ctx.add(
        rod((w / 2 - 0.03, -d / 4, h), (w / 2 - 0.03 - 0.12, -d / 4, h + 0.28 * ctx.s), 0.004, sections=6),
        "metal",
        "silver",
    )
    if ctx.chance(0.6):
        ctx.add(rod((-w * 0.35, 0, h), (-w * 0.35, 0, h + 0.04), 0.008), "plastic", "black")
        ctx.add(rod((w * 0.2, 0, h), (w * 0.2, 0, h + 0.04), 0.008), "plastic", "black")
        ctx.add(rod((-w * 0.35, 0, h + 0.04), (w * 0.2, 0, h + 0.04), 0.008), "plastic", "black")
        ctx.feature("a carrying handle")
    ctx.feature("a silver antenna")
    ctx.feature("a round speaker grille")


@category(
    "speaker",
    "surface",
    ["living", "office"],
    0.6,
    materials=["wood", "plastic"],
    colours=("black", "dark brown", "white", "light brown", "dark grey"),
)
def speaker(ctx: Ctx) -> None:
    w, d, h = ctx.u(0.16, 0.22) * ctx.s, ctx.u(0.2, 0.26), ctx.u(0.28, 0.36) * ctx.s
    ctx.add(box(w, d, h))
    ctx.add(rod((0, d / 2 - 0.002, h * 0.35), (0, d / 2 + 0.012, h * 0.35), w * 0.38, sections=20), "plastic", "black")
    ctx.add(rod((0, d / 2 + 0.01, h * 0.35), (0, d / 2 + 0.018, h * 0.35), w * 0.12, sections=12), "metal", "dark grey")
    ctx.add(rod((0, d / 2 - 0.002, h * 0.78), (0, d / 2 + 0.01, h * 0.78), w * 0.14, sections=12), "metal", "silver")
    ctx.feature("a woofer and a tweeter")


def _shade(ctx: Ctx, r_bot: float, r_top: float, h: float, z: float, colour: str) -> None:
    ctx.add(vessel([(r_bot, 0), (r_top, h)], 0.004, z=z, sections=20), "fabric", colour)


@category(
    "table_lamp",
    "surface",
    ["bedroom", "living"],
    1.5,
    materials=["ceramic", "metal", "glass", "wood"],
    colours=("white", "cream", "blue", "green", "black", "gold", "grey", "teal", "orange"),
    styles=["gourd", "column", "candlestick"],
)
def table_lamp(ctx: Ctx) -> None:
    s = ctx.s
    if ctx.style == "gourd":
        base_h = ctx.u(0.22, 0.3) * s
        ctx.add(revolve([(0, 0), (0.05, 0), (0.1, base_h * 0.4), (0.05, base_h * 0.85), (0.02, base_h), (0, base_h)]))
    elif ctx.style == "column":
        base_h = ctx.u(0.25, 0.32) * s
        ctx.add(cyl(0.06, base_h, sections=16))
    else:
        base_h = ctx.u(0.28, 0.36) * s
        ctx.add(cyl(0.07, 0.02, sections=16))
        ctx.add(cyl(0.012, base_h))
    ctx.add(cyl(0.008, 0.12, 0, 0, base_h), "metal", "silver")
    sc = ctx.pick(SHADE_COLOURS)
    sh = ctx.u(0.16, 0.22) * s
    _shade(ctx, ctx.u(0.14, 0.18) * s, ctx.u(0.09, 0.12) * s, sh, base_h + 0.08, sc)
    ctx.feature(f"a {sc} lampshade")


@category(
    "desk_lamp",
    "surface",
    ["office", "bedroom"],
    1.0,
    materials=["metal", "plastic"],
    colours=("black", "white", "silver", "red", "yellow", "green", "blue"),
    styles=["articulated", "banker"],
)
def desk_lamp(ctx: Ctx) -> None:
    if ctx.style == "banker":
        stem, r = ctx.u(0.26, 0.34) * ctx.s, ctx.u(0.1, 0.13) * ctx.s
        ctx.add(cyl(0.07, 0.02, sections=16), "metal", "gold")
        ctx.add(cyl(0.008, stem, 0, 0, 0.02), "metal", "gold")
        shade = revolve([(0, 0), (r, 0), (r - 0.01, 0.01), (0.03, 0.05), (0, 0.05)], sections=16)
        shade.apply_scale((1.0, 0.45, 1.0))
        shade.apply_translation((0, 0.02, stem))
        ctx.add(shade, "glass")
        ctx.feature("a glass shade and a brass stem")
        return
    ctx.add(cyl(0.08, 0.025, sections=16))
    a = ctx.u(0.28, 0.36)
    elbow = np.array([0.0, -0.05 + ctx.u(-0.05, 0.05), 0.025 + a])
    head = elbow + (0, ctx.u(0.22, 0.3), ctx.u(-0.02, 0.08))
    ctx.add(rod((0, 0, 0.025), elbow, 0.01))
    ctx.add(rod(elbow, head, 0.01))
    ctx.add(ellipsoid(0.02, 0.02, 0.02, *elbow, count=8))
    cone = revolve([(0, 0), (0.07, 0), (0.025, 0.1), (0, 0.1)], sections=16)
    ctx.add(moved(rotated(cone, 0.4, (1, 0, 0)), head - (0, 0, 0.09)))
    ctx.feature("an adjustable arm")


@category(
    "floor_lamp",
    "floor",
    ["living", "bedroom", "office"],
    1.0,
    materials=["metal", "wood"],
    colours=("black", "silver", "gold", "white", "dark brown"),
    styles=["straight", "arc", "tripod"],
)
def floor_lamp(ctx: Ctx) -> None:
    h = ctx.u(1.5, 1.75) * ctx.s**0.5
    sc = ctx.pick(SHADE_COLOURS)
    if ctx.style == "tripod":
        for x, y in ring_positions(3, 0.28, ctx.u(0, 2)):
            ctx.add(rod((x, y, 0), (0, 0, h * 0.75), 0.014))
        ctx.add(rod((0, 0, h * 0.7), (0, 0, h - 0.1), 0.012))
        ctx.feature("three wooden legs" if ctx.material == "wood" else "a tripod base")
        _shade(ctx, 0.22, 0.2, 0.28, h - 0.2, sc)
    elif ctx.style == "arc":
        ctx.add(cyl(0.16, 0.04, sections=20), "stone", "white")
        pts = [(0, 0, 0.04), (0, 0.1, h * 0.7), (0, 0.35, h), (0, 0.7, h * 0.95)]
        for p0, p1 in zip(pts[:-1], pts[1:]):
            ctx.add(rod(p0, p1, 0.012))
        ctx.add(moved(_flip_cone(0.18, 0.16), (0, 0.7, h * 0.95 - 0.16)), "metal")
        ctx.feature("an arched arm and a marble base")
    else:
        ctx.add(cyl(0.15, 0.03, sections=20))
        ctx.add(cyl(0.014, h - 0.25, 0, 0, 0.03))
        _shade(ctx, 0.2, 0.16, 0.3, h - 0.3, sc)
        ctx.feature(f"a {sc} shade")


def _flip_cone(r: float, h: float):
    """Downward-opening dome shade (open side at the bottom)."""
    return revolve([(0, 0), (r, 0), (r - 0.004, 0.004), (0.02, h - 0.004), (0, h)], sections=20)


@category(
    "ceiling_light",
    "ceiling",
    ROOM_KINDS,
    2.5,
    materials=["glass", "metal", "fabric"],
    colours=("white", "white", "cream", "black", "gold", "silver"),
    styles=["pendant", "flush", "chandelier"],
)
def ceiling_light(ctx: Ctx) -> None:
    s = ctx.s
    if ctx.style == "flush":
        r = ctx.u(0.18, 0.26) * s
        ctx.add(cyl(r + 0.01, 0.02, 0, 0, 0.08), "metal", "white")
        ctx.add(revolve([(0, 0), (r * 0.7, 0.01), (r, 0.08), (0, 0.08)], sections=24), "glass", "white")
        ctx.feature("a frosted dome")
        return
    drop = ctx.u(0.4, 0.8)
    ctx.add(cyl(0.05, 0.025, 0, 0, drop + 0.2), "metal", "white")
    ctx.add(cyl(0.004, drop, 0, 0, 0.2), "plastic", "black")
    if ctx.style == "pendant":
        r = ctx.u(0.15, 0.22) * s
        ctx.add(_flip_cone(r, 0.2))
        ctx.feature("a long cord")
        return
    r = ctx.u(0.25, 0.35) * s
    ctx.add(cyl(0.03, 0.2, 0, 0, 0.0), "metal", "gold")
    for x, y in ring_positions(6, r, 0.0):
        ctx.add(rod((0, 0, 0.05), (x, y, 0.08), 0.008), "metal", "gold")
        ctx.add(cyl(0.012, 0.08, x, y, 0.08), "ceramic", "cream")
        ctx.add(ellipsoid(0.018, 0.018, 0.028, x, y, 0.18, count=8), "glass", "cream")
    ctx.feature("six candle bulbs")


@category(
    "keyboard", "surface", ["office"], 0.7, materials=["plastic"], colours=("black", "white", "dark grey", "silver")
)
def keyboard(ctx: Ctx) -> None:
    w, d = ctx.u(0.36, 0.45) * ctx.s, ctx.u(0.12, 0.15)
    ctx.add(box(w, d, 0.02))
    keycol = "white" if ctx.colour in ("black", "dark grey") else "dark grey"
    for i in range(5):
        ctx.add(box(w - 0.03, d / 5 - 0.008, 0.008, 0, -d / 2 + d / 10 + i * d / 5, 0.02), "plastic", keycol)
    ctx.feature("rows of keys")


@category(
    "printer", "surface", ["office"], 0.6, materials=["plastic"], colours=("white", "black", "dark grey", "light grey")
)
def printer(ctx: Ctx) -> None:
    w, d, h = ctx.u(0.38, 0.46) * ctx.s, ctx.u(0.3, 0.38), ctx.u(0.18, 0.25)
    ctx.add(box(w, d, h))
    ctx.add(
        rotated(box(w * 0.6, 0.006, 0.2, 0, -d / 2 + 0.02, h - 0.05), 0.4, (1, 0, 0), (0, -d / 2 + 0.02, h - 0.05)),
        "paper",
        "white",
    )
    ctx.add(box(w * 0.6, 0.12, 0.01, 0, d / 2 + 0.05, h * 0.35), "plastic", "dark grey")
    ctx.add(box(w * 0.2, 0.008, 0.04, w * 0.3, d / 2, h - 0.06), "glass", "black")
    ctx.feature("a paper tray")
    ctx.surface_heights.append(h)


@category(
    "fan",
    "floor",
    ["bedroom", "living", "office"],
    0.4,
    materials=["plastic", "metal"],
    colours=("white", "black", "silver", "light blue"),
)
def fan(ctx: Ctx) -> None:
    h = ctx.u(0.9, 1.25) * ctx.s**0.5
    ctx.add(cyl(0.17, 0.04, sections=20))
    ctx.add(cyl(0.018, h - 0.2, 0, 0, 0.04))
    c = np.array([0, 0.0, h - 0.16])
    ctx.add(rod(c + (0, -0.12, 0), c + (0, 0.02, 0), 0.06, sections=12))
    for k in range(3):
        ctx.add(rotated(box(0.07, 0.01, 0.14, 0, 0.05, h - 0.16), 2 * np.pi * k / 3, (0, 1, 0), c))
    ctx.add(torus(0.17, 0.006, c + (0, 0.06, 0), axis="y", sections=20), "metal", "silver")
    ctx.add(torus(0.17, 0.006, c + (0, 0.0, 0), axis="y", sections=20), "metal", "silver")
    ctx.feature("a round safety cage")
