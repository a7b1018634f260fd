"""Toys, musical instruments, sports gear and travel items. Front faces +y."""

from __future__ import annotations

import numpy as np
import trimesh

from generators.asset_library.core import Ctx, box, category, cyl, ellipsoid, ring_positions, rod, rotated, torus

TOY_COLOURS = ("red", "blue", "yellow", "green", "orange", "purple", "pink", "teal")


@category(
    "teddy_bear",
    "surface",
    ["bedroom", "living"],
    0.5,
    materials=["fabric"],
    colours=("brown", "light brown", "tan", "cream", "white", "pink", "grey"),
)
def teddy_bear(ctx: Ctx) -> None:
    s = ctx.s * ctx.u(0.9, 1.1)
    ctx.add(ellipsoid(0.09 * s, 0.07 * s, 0.1 * s, 0, 0, 0.1 * s, count=12))
    ctx.add(ellipsoid(0.07 * s, 0.065 * s, 0.065 * s, 0, 0.005, 0.25 * s, count=12))
    ctx.add(ellipsoid(0.03 * s, 0.025 * s, 0.022 * s, 0, 0.06 * s, 0.24 * s, count=8), "fabric", "cream")
    ctx.add(ellipsoid(0.01 * s, 0.008, 0.008 * s, 0, 0.085 * s, 0.25 * s, count=6), "plastic", "black")
    for sx in (-1, 1):
        ctx.add(ellipsoid(0.025 * s, 0.015 * s, 0.025 * s, sx * 0.05 * s, 0, 0.31 * s, count=8))
        ctx.add(ellipsoid(0.03 * s, 0.05 * s, 0.03 * s, sx * 0.06 * s, 0.06 * s, 0.03 * s, count=8))
        ctx.add(ellipsoid(0.025 * s, 0.025 * s, 0.06 * s, sx * 0.09 * s, 0.02 * s, 0.13 * s, count=8))
        ctx.add(
            ellipsoid(0.008 * s, 0.006, 0.008 * s, sx * 0.025 * s, 0.06 * s, 0.275 * s, count=6), "plastic", "black"
        )
    if ctx.chance(0.5):
        c = ctx.pick(("red", "blue", "pink", "green"))
        ctx.add(ellipsoid(0.03 * s, 0.015 * s, 0.015 * s, 0, 0.055 * s, 0.19 * s, count=8), "fabric", c)
        ctx.feature(f"a {c} bow tie")
    ctx.feature("round ears")


@category(
    "toy_ball", "floor", ["bedroom", "living"], 0.4, materials=["rubber", "plastic"], colours=TOY_COLOURS, noun="ball"
)
def toy_ball(ctx: Ctx) -> None:
    r = ctx.u(0.08, 0.12) * ctx.s
    ctx.add(ellipsoid(r, r, r, 0, 0, r, count=16))
    c = ctx.pick(("white", "yellow", "blue", "red"))
    ctx.add(torus(r * 1.0, 0.012, (0, 0, r), axis="x", sections=20), "rubber", c)
    ctx.feature(f"a {c} stripe")


@category("toy_car", "surface", ["bedroom", "living"], 0.3, materials=["plastic", "metal"], colours=TOY_COLOURS)
def toy_car(ctx: Ctx) -> None:
    s = ctx.s
    L, w = ctx.u(0.16, 0.25) * s, ctx.u(0.08, 0.11) * s
    wr = 0.022 * s
    ctx.add(box(w, L, 0.045 * s, 0, 0, wr * 0.8))
    ctx.add(box(w * 0.85, L * 0.5, 0.04 * s, 0, -L * 0.05, wr * 0.8 + 0.045 * s))
    ctx.add(box(w * 0.87, L * 0.35, 0.03 * s, 0, -L * 0.05, wr * 0.8 + 0.05 * s), "glass", "light blue")
    for sx in (-1, 1):
        for sy in (-1, 1):
            ctx.add(
                rod(
                    (sx * w / 2 - sx * 0.01, sy * L * 0.32, wr),
                    (sx * w / 2 + sx * 0.008, sy * L * 0.32, wr),
                    wr,
                    sections=12,
                ),
                "rubber",
                "black",
            )
    ctx.feature("black wheels")


@category(
    "toy_blocks",
    "surface",
    ["bedroom", "living"],
    0.3,
    materials=["wood", "plastic"],
    colours=TOY_COLOURS,
    styles=["tower", "pyramid", "row"],
    noun="set of toy blocks",
)
def toy_blocks(ctx: Ctx) -> None:
    a = ctx.u(0.04, 0.06) * ctx.s
    if ctx.style == "pyramid":
        cells = [(i + 0.5 * k, k) for k in range(3) for i in range(3 - k)]
    else:
        n = int(ctx.rng.integers(3, 5))
        cells = [(0, k) for k in range(n)] if ctx.style == "tower" else [(i * 1.15, 0) for i in range(n)]
    for i, (x, k) in enumerate(cells):
        turn = ctx.u(-0.2, 0.2) if ctx.style == "tower" else 0.0
        ctx.add(
            rotated(box(a, a, a, x * a, 0, k * a), turn, (0, 0, 1), (x * a, 0, 0)),
            None,
            None if i == 0 else ctx.pick(TOY_COLOURS + ("white",)),
        )
    ctx.feature(f"{len(cells)} coloured cubes")


@category(
    "guitar",
    "floor",
    ["living", "bedroom"],
    0.3,
    materials=["wood"],
    colours=("light brown", "brown", "dark brown", "red", "black", "white", "tan"),
    styles=["acoustic", "electric"],
)
def guitar(ctx: Ctx) -> None:
    s = ctx.s**0.3
    t = 0.1 if ctx.style == "acoustic" else 0.045
    lean = 0.2
    parts = [
        (ellipsoid(0.19 * s, t / 2, 0.17 * s, 0, 0, 0.26), None, None),
        (ellipsoid(0.15 * s, t / 2, 0.13 * s, 0, 0, 0.52), None, None),
        (box(0.05, 0.025, 0.5, 0, 0.0, 0.6), "wood", "dark brown"),
        (box(0.08, 0.02, 0.17, 0, 0, 1.1), "wood", "dark brown"),
    ]
    if ctx.style == "acoustic":
        parts.append((rod((0, t / 2 - 0.005, 0.44), (0, t / 2 + 0.002, 0.44), 0.045, sections=16), "plastic", "black"))
        ctx.feature("a round sound hole")
    else:
        parts.append((box(0.12, 0.006, 0.2, 0.02, t / 2, 0.25), "plastic", "white"))
        ctx.feature("a white pickguard")
    for mesh, mat, col in parts:
        mesh.apply_transform(_lean(lean))
        ctx.add(mesh, mat, col)
    for sx in (-1, 1):
        ctx.add(rod((sx * 0.15, 0.05, 0.0), (0, -0.06, 0.55), 0.01), "metal", "black")
    ctx.feature("a stand")


def _lean(angle: float) -> np.ndarray:
    """Tilt back (towards -y) about the x axis through the origin, as an instrument on a stand."""
    return trimesh.transformations.rotation_matrix(angle, (1, 0, 0))


@category(
    "piano",
    "wall",
    ["living"],
    0.3,
    materials=["wood"],
    colours=("black", "black", "dark brown", "white", "brown"),
    styles=["upright", "digital"],
)
def piano(ctx: Ctx) -> None:
    w = ctx.u(1.3, 1.5)
    if ctx.style == "upright":
        d, h = ctx.u(0.55, 0.65), ctx.u(1.1, 1.3)
        ctx.add(box(w, d * 0.55, h, 0, -d * 0.225, 0))
        for sx in (-1, 1):
            ctx.add(box(0.05, d, 0.72, sx * (w / 2 - 0.025), 0, 0))
        ctx.add(box(w - 0.1, d * 0.45, 0.05, 0, d * 0.275, 0.68))
        key_z = 0.73
        ctx.feature("a music stand" if ctx.chance(0.5) else "brass pedals")
        ctx.add(box(0.3, 0.06, 0.03, 0, d / 2 - 0.05, 0.05), "metal", "gold")
    else:
        d = ctx.u(0.3, 0.38)
        ctx.add(box(w, d, 0.12, 0, 0, 0.7))
        for sx in (-1, 1):
            ctx.add(box(0.04, d, 0.7, sx * (w / 2 - 0.02), 0, 0))
        key_z = 0.79
    ctx.add(
        box(w - 0.14, 0.15, 0.025, 0, d / 2 - 0.1 if ctx.style == "upright" else d / 2 - 0.09, key_z),
        "plastic",
        "white",
    )
    for x in np.linspace(-w / 2 + 0.12, w / 2 - 0.12, 20):
        ctx.add(
            box(0.012, 0.09, 0.012, x, d / 2 - 0.14 if ctx.style == "upright" else d / 2 - 0.12, key_z + 0.025),
            "plastic",
            "black",
        )
    ctx.feature("black and white keys")


@category(
    "drum",
    "floor",
    ["living", "bedroom"],
    0.2,
    materials=["wood", "metal"],
    colours=("red", "black", "white", "blue", "silver", "dark red"),
)
def drum(ctx: Ctx) -> None:
    r, h = ctx.u(0.17, 0.22) * ctx.s, ctx.u(0.14, 0.2)
    z0 = ctx.u(0.5, 0.6)
    for x, y in ring_positions(3, 0.25, 0.3):
        ctx.add(rod((x, y, 0), (0, 0, z0 - 0.05), 0.01), "metal", "silver")
    ctx.add(cyl(0.012, 0.06, 0, 0, z0 - 0.06), "metal", "silver")
    ctx.add(cyl(r, h, 0, 0, z0, sections=24))
    ctx.add(cyl(r + 0.002, 0.004, 0, 0, z0 + h, sections=24), "plastic", "white")
    for z in (z0, z0 + h):
        ctx.add(torus(r + 0.006, 0.007, (0, 0, z), sections=24), "metal", "silver")
    ctx.add(rod((-0.15, 0.25, z0 + h + 0.02), (0.1, 0.2, z0 + h + 0.04), 0.007), "wood", "tan")
    ctx.feature("a white drumhead and chrome rims")


@category(
    "dumbbell",
    "floor",
    ["bedroom", "living"],
    0.3,
    materials=["metal", "rubber"],
    colours=("black", "silver", "dark grey", "red", "blue"),
)
def dumbbell(ctx: Ctx) -> None:
    r, L = ctx.u(0.05, 0.08) * ctx.s, ctx.u(0.3, 0.38) * ctx.s
    ctx.add(rod((-L / 2, 0, r), (L / 2, 0, r), 0.015, sections=10), "metal", "silver")
    for sx in (-1, 1):
        ctx.add(rod((sx * L * 0.28, 0, r), (sx * L / 2, 0, r), r, sections=8 if ctx.chance(0.5) else 16))
    ctx.feature("a chrome grip")


@category(
    "basketball", "floor", ["bedroom", "corridor"], 0.3, materials=["rubber"], colours=("orange", "orange", "dark red")
)
def basketball(ctx: Ctx) -> None:
    r = ctx.u(0.113, 0.122)  # sizes 6 and 7
    ctx.add(ellipsoid(r, r, r, 0, 0, r, count=16))
    for axis in ("x", "y"):
        ctx.add(torus(r, 0.003, (0, 0, r), axis=axis, sections=24), "rubber", "black")
    ctx.add(torus(r * 0.999, 0.003, (0, 0, r), axis="z", sections=24), "rubber", "black")
    ctx.feature("black seams")


@category(
    "yoga_mat",
    "floor",
    ["bedroom", "living"],
    0.3,
    materials=["rubber"],
    colours=("purple", "blue", "green", "pink", "teal", "black", "grey"),
    noun="rolled yoga mat",
)
def yoga_mat(ctx: Ctx) -> None:
    r, L = ctx.u(0.06, 0.08), ctx.u(0.6, 0.68)
    ctx.add(rod((-L / 2, 0, r), (L / 2, 0, r), r, sections=16))
    ctx.add(rod((-L / 2 - 0.002, 0, r), (L / 2 + 0.002, 0, r), r * 0.35, sections=12), "rubber", "dark grey")
    for x in (-L / 4, L / 4):
        ctx.add(torus(r + 0.003, 0.006, (x, 0, r), axis="x", sections=16), "fabric", "black")
    ctx.feature("two straps")


@category(
    "bicycle",
    "floor",
    ["corridor"],
    0.2,
    materials=["metal"],
    colours=("red", "blue", "black", "white", "green", "yellow", "silver"),
)
def bicycle(ctx: Ctx) -> None:
    R = ctx.u(0.31, 0.35) * ctx.s**0.5
    wb = ctx.u(1.0, 1.1) * ctx.s**0.5
    rear, front = np.array([0, -wb / 2, R]), np.array([0, wb / 2, R])
    for c in (rear, front):
        ctx.add(torus(R - 0.02, 0.02, c, axis="x", sections=24), "rubber", "black")
        ctx.add(rod(c - (0.02, 0, 0), c + (0.02, 0, 0), 0.03), "metal", "silver")
    crank = np.array([0, -wb * 0.05, R * 0.95])
    seat_top = np.array([0, -wb * 0.18, R + 0.55])
    head = np.array([0, wb * 0.35, R + 0.5])
    for a, b in (
        (rear, crank),
        (crank, seat_top),
        (rear, seat_top - (0, 0, 0.08)),
        (crank, head - (0, 0, 0.12)),
        (seat_top - (0, 0, 0.08), head - (0, 0, 0.02)),
        (head, front),
    ):
        ctx.add(rod(a, b, 0.018))
    ctx.add(ellipsoid(0.07, 0.13, 0.03, *(seat_top + (0, 0, 0.02)), count=10), "leather", "black")
    ctx.add(rod(head + (-0.25, 0, 0.05), head + (0.25, 0, 0.05), 0.013), "metal", "silver")
    ctx.add(rod(head, head + (0, 0, 0.05), 0.015), "metal", "silver")
    ctx.add(cyl(0.09, 0.01, crank[0] + 0.03, crank[1], crank[2] - 0.005), "metal", "silver")
    ctx.feature("black tyres")
    ctx.feature("a leather saddle")


@category(
    "suitcase",
    "floor",
    ["bedroom", "corridor"],
    0.3,
    materials=["plastic", "fabric", "leather"],
    colours=("black", "navy", "red", "silver", "grey", "teal", "brown"),
    styles=["upright", "trunk"],
)
def suitcase(ctx: Ctx) -> None:
    if ctx.style == "trunk":
        w, d, h = ctx.u(0.7, 0.9), ctx.u(0.45, 0.55), ctx.u(0.35, 0.45)
        ctx.add(box(w, d, h))
        for x in (-w / 3, w / 3):
            ctx.add(box(0.05, d + 0.01, h + 0.01, x, 0, 0), "leather", "dark brown")
        ctx.add(box(0.1, 0.02, 0.06, 0, d / 2, h - 0.1), "metal", "gold")
        ctx.feature("leather straps and a brass lock")
        return
    w, d, h = ctx.u(0.38, 0.48) * ctx.s, ctx.u(0.22, 0.28), ctx.u(0.55, 0.72) * ctx.s
    ctx.add(box(w, d, h, 0, 0, 0.05))
    for sx in (-1, 1):
        for sy in (-1, 1):
            ctx.add(
                ellipsoid(0.025, 0.025, 0.025, sx * (w / 2 - 0.04), sy * (d / 2 - 0.04), 0.025, count=8),
                "rubber",
                "black",
            )
    for sx in (-1, 1):
        ctx.add(rod((sx * 0.1, -d / 2 + 0.03, h + 0.05), (sx * 0.1, -d / 2 + 0.03, h + 0.3), 0.008), "metal", "silver")
    ctx.add(rod((-0.11, -d / 2 + 0.03, h + 0.3), (0.11, -d / 2 + 0.03, h + 0.3), 0.014), "plastic", "black")
    ctx.add(box(0.12, 0.02, 0.03, 0, d / 2 + 0.01, h - 0.05), "plastic", "black")
    ctx.feature("a telescopic handle and wheels")
