"""Decor and plants. Wall-mounted items have their back on the min-y side."""

from __future__ import annotations

import numpy as np
import trimesh

from generators.asset_library.core import (
    Ctx,
    box,
    category,
    cyl,
    ellipsoid,
    revolve,
    ring_positions,
    rod,
    rotated,
    torus,
    vessel,
)

ART_COLOURS = (
    "red",
    "blue",
    "yellow",
    "green",
    "orange",
    "teal",
    "pink",
    "navy",
    "purple",
    "cream",
    "dark red",
    "olive",
)
POT_COLOURS = ("orange", "white", "grey", "black", "cream", "teal", "light brown")
LEAF_COLOURS = ("green", "dark green", "olive")


@category(
    "vase",
    "surface",
    ["living", "dining", "bedroom"],
    1.2,
    materials=["ceramic", "ceramic", "glass", "stone"],
    colours=ART_COLOURS + ("white", "black"),
    styles=["bulb", "cylinder", "amphora"],
)
def vase(ctx: Ctx) -> None:
    h = ctx.u(0.2, 0.35) * ctx.s
    r = ctx.u(0.06, 0.09) * ctx.s
    prof = {
        "bulb": [(r * 0.6, 0), (r, h * 0.35), (r * 0.35, h * 0.8), (r * 0.45, h)],
        "cylinder": [(r * 0.8, 0), (r * 0.8, h)],
        "amphora": [(r * 0.5, 0), (r, h * 0.55), (r * 0.4, h * 0.85), (r * 0.6, h)],
    }[ctx.style]
    ctx.add(vessel(prof, 0.005))
    if ctx.chance(0.5):
        fc = ctx.pick(("red", "yellow", "white", "pink", "purple", "orange"))
        for x, y in ring_positions(5, r * 0.2, ctx.u(0, 1)):
            tip = (x * 6, y * 6, h + ctx.u(0.12, 0.22))
            ctx.add(rod((x, y, h * 0.5), tip, 0.003, sections=5), "foliage", "green")
            ctx.add(ellipsoid(0.025, 0.025, 0.02, *tip, count=8), "fabric", fc)
        ctx.feature(f"{fc} flowers")


@category(
    "picture_frame",
    "surface",
    ["living", "bedroom", "office"],
    1.0,
    materials=["wood", "metal"],
    colours=("black", "white", "gold", "silver", "light brown", "dark brown"),
    noun="photo frame",
)
def picture_frame(ctx: Ctx) -> None:
    w, h = ctx.u(0.13, 0.22) * ctx.s, ctx.u(0.18, 0.28) * ctx.s
    tilt = 0.2
    ctx.add(rotated(box(w, 0.015, h, 0, 0, 0.0), -tilt, (1, 0, 0)))
    ctx.add(rotated(box(w - 0.03, 0.004, h - 0.03, 0, 0.009, 0.015), -tilt, (1, 0, 0)), "paper", ctx.pick(ART_COLOURS))
    ctx.add(rotated(box(0.03, 0.005, h * 0.7, 0, -0.01, 0), 0.3, (1, 0, 0)))
    ctx.feature("a photo")


@category(
    "painting",
    "wall_mounted",
    ["living", "bedroom", "dining", "corridor", "office"],
    2.0,
    materials=["wood", "metal"],
    colours=("gold", "black", "white", "light brown", "dark brown", "silver"),
    styles=["abstract", "landscape", "portrait"],
)
def painting(ctx: Ctx) -> None:
    if ctx.style == "portrait":
        w, h = ctx.u(0.4, 0.6) * ctx.s, ctx.u(0.55, 0.8) * ctx.s
    else:
        w, h = ctx.u(0.6, 1.1) * ctx.s, ctx.u(0.4, 0.7) * ctx.s
    fw = 0.04
    ctx.add(box(w, 0.03, fw, 0, 0, 0))
    ctx.add(box(w, 0.03, fw, 0, 0, h - fw))
    for sx in (-1, 1):
        ctx.add(box(fw, 0.03, h - 2 * fw, sx * (w - fw) / 2, 0, fw))
    cw, ch = w - 2 * fw, h - 2 * fw
    if ctx.style == "landscape":
        sky, land = ctx.pick(("light blue", "cream", "orange")), ctx.pick(("green", "olive", "dark green", "tan"))
        ctx.add(box(cw, 0.01, ch * 0.55, 0, -0.005, fw + ch * 0.45), "fabric", sky)
        ctx.add(box(cw, 0.01, ch * 0.45, 0, -0.005, fw), "fabric", land)
        ctx.feature(f"a {land} landscape under a {sky} sky")
        return
    bg = ctx.pick(("cream", "white", "beige", "navy", "black"))
    ctx.add(box(cw, 0.01, ch, 0, -0.005, fw), "fabric", bg)
    cols = [ctx.pick(ART_COLOURS) for _ in range(3)]
    for c in cols:
        bw, bh = ctx.u(0.15, 0.45) * cw, ctx.u(0.15, 0.45) * ch
        x, z = ctx.u(-cw / 2 + bw / 2, cw / 2 - bw / 2), ctx.u(fw, fw + ch - bh)
        ctx.add(box(bw, 0.004, bh, x, 0.0025, z), "fabric", c)
    ctx.feature(f"{cols[0]} and {cols[1]} shapes" if ctx.style == "abstract" else "a figure")


@category(
    "clock",
    "wall_mounted",
    ["kitchen", "living", "office", "corridor"],
    1.0,
    materials=["plastic", "wood", "metal"],
    colours=("white", "black", "red", "silver", "light brown", "gold", "teal"),
    styles=["round", "square"],
)
def clock(ctx: Ctx) -> None:
    r = ctx.u(0.13, 0.2) * ctx.s
    c = np.array([0.0, 0.02, r])
    if ctx.style == "round":
        ctx.add(torus(r, 0.015, c, axis="y", sections=24))
        ctx.add(rod(c - (0, 0.02, 0), c + (0, 0.01, 0), r, sections=24), "paper", "white")
    else:
        ctx.add(box(2 * r + 0.03, 0.04, 2 * r + 0.03, 0, 0, 0))
        ctx.add(box(2 * r - 0.02, 0.004, 2 * r - 0.02, 0, 0.02, 0.025), "paper", "white")
        c = c + (0, 0, 0.015)
    for k in range(12):
        a = 2 * np.pi * k / 12
        ctx.add(
            box(
                0.008,
                0.004,
                0.025 if k % 3 == 0 else 0.012,
                c[0] + 0.85 * r * np.sin(a),
                c[1] + 0.012,
                c[2] + 0.85 * r * np.cos(a) - 0.008,
            ),
            "plastic",
            "black",
        )
    hand_a, hand_b = ctx.u(0, 2 * np.pi), ctx.u(0, 2 * np.pi)
    ctx.add(
        rod(c + (0, 0.014, 0), c + (0.5 * r * np.sin(hand_a), 0.014, 0.5 * r * np.cos(hand_a)), 0.005, sections=6),
        "metal",
        "black",
    )
    ctx.add(
        rod(c + (0, 0.016, 0), c + (0.75 * r * np.sin(hand_b), 0.016, 0.75 * r * np.cos(hand_b)), 0.003, sections=6),
        "metal",
        "black",
    )
    ctx.feature("black hands")


@category(
    "mirror",
    "wall_mounted",
    ["bathroom", "bedroom", "corridor"],
    1.0,
    materials=["wood", "metal"],
    colours=("gold", "black", "white", "silver", "light brown"),
    styles=["rectangular", "round", "tall"],
)
def mirror(ctx: Ctx) -> None:
    if ctx.style == "round":
        r = ctx.u(0.25, 0.4) * ctx.s
        ctx.add(torus(r, 0.02, (0, 0.02, r), axis="y", sections=28))
        ctx.add(rod((0, 0.0, r), (0, 0.025, r), r, sections=28), "glass", "light blue")
        ctx.feature("a round frame")
        return
    w, h = (ctx.u(0.5, 0.8), ctx.u(0.6, 0.9)) if ctx.style == "rectangular" else (ctx.u(0.4, 0.55), ctx.u(1.3, 1.6))
    w, h = w * ctx.s, h * ctx.s
    ctx.add(box(w, 0.025, h))
    ctx.add(box(w - 0.06, 0.006, h - 0.06, 0, 0.0125, 0.03), "glass", "light blue")
    ctx.feature("a thin frame" if ctx.style == "rectangular" else "a full-length glass")


@category(
    "rug",
    "floor",
    ["living", "bedroom", "dining", "corridor"],
    1.2,
    materials=["fabric"],
    colours=ART_COLOURS + ("beige", "grey", "white"),
    styles=["rectangular", "round", "runner"],
)
def rug(ctx: Ctx) -> None:
    t = 0.012
    border = ctx.pick(("cream", "navy", "dark red", "black", "beige", "grey"))
    if ctx.style == "round":
        r = ctx.u(0.6, 0.9) * ctx.s
        ctx.add(cyl(r, t, sections=32), "fabric", border)
        ctx.add(cyl(r - 0.08, t, 0, 0, 0.001, sections=32))
    else:
        w, d = (ctx.u(1.4, 2.2), ctx.u(1.0, 1.6)) if ctx.style == "rectangular" else (ctx.u(0.6, 0.8), ctx.u(1.8, 2.6))
        w, d = w * ctx.s, d * ctx.s
        ctx.add(box(w, d, t), "fabric", border)
        ctx.add(box(w - 0.16, d - 0.16, t, 0, 0, 0.001))
        if ctx.chance(0.5):
            ctx.add(box(w * 0.3, d * 0.3, t, 0, 0, 0.002), "fabric", border)
            ctx.feature("a central medallion")
    ctx.feature(f"a {border} border")


@category(
    "cushion",
    "surface",
    ["living", "bedroom"],
    1.0,
    materials=["fabric", "fabric", "leather"],
    colours=ART_COLOURS + ("white", "grey"),
    styles=["square", "round", "bolster"],
)
def cushion(ctx: Ctx) -> None:
    s = ctx.s
    if ctx.style == "round":
        ctx.add(ellipsoid(0.2 * s, 0.2 * s, 0.07, 0, 0, 0.07, count=14))
        ctx.add(ellipsoid(0.02, 0.02, 0.01, 0, 0, 0.135, count=8), "fabric", "white")
    elif ctx.style == "bolster":
        ctx.add(rod((-0.23 * s, 0, 0.08), (0.23 * s, 0, 0.08), 0.08, sections=14))
    else:
        side = ctx.u(0.38, 0.48) * s
        ctx.add(ellipsoid(side / 2 * 1.15, side / 2 * 1.15, 0.08, 0, 0, 0.08, count=14))
        ctx.add(box(side, side, 0.06, 0, 0, 0.05))
        if ctx.chance(0.4):
            ctx.feature("piped edges")


@category(
    "candle",
    "surface",
    ["living", "dining", "bedroom", "bathroom"],
    0.6,
    materials=["wax"],
    colours=("white", "cream", "red", "yellow", "purple", "light blue"),
    styles=["pillar", "taper", "jar"],
)
def candle(ctx: Ctx) -> None:
    if ctx.style == "jar":
        r, h = ctx.u(0.035, 0.05), ctx.u(0.07, 0.1)
        ctx.add(vessel([(r, 0), (r, h)], 0.003), "glass", "light grey")
        ctx.add(cyl(r - 0.004, h * 0.7, 0, 0, 0.003))
        ctx.feature("a glass jar")
        return
    if ctx.style == "taper":
        ctx.add(
            revolve(
                [(0, 0), (0.05, 0), (0.05, 0.01), (0.012, 0.02), (0.012, 0.06), (0.02, 0.06), (0.02, 0.07), (0, 0.07)]
            ),
            "metal",
            "gold",
        )
        r, h, z = 0.01, ctx.u(0.18, 0.25) * ctx.s, 0.06
        ctx.feature("a brass holder")
    else:
        r, h, z = ctx.u(0.03, 0.045) * ctx.s, ctx.u(0.08, 0.15) * ctx.s, 0.0
    ctx.add(cyl(r, h, 0, 0, z, sections=16))
    ctx.add(cyl(0.0015, 0.012, 0, 0, z + h, sections=6), "fabric", "black")


@category(
    "sculpture",
    "surface",
    ["living", "office", "corridor"],
    0.4,
    materials=["stone", "metal", "ceramic", "wood"],
    colours=("white", "black", "gold", "silver", "grey", "teal", "light brown"),
    styles=["stacked", "ring", "figure"],
)
def sculpture(ctx: Ctx) -> None:
    s = ctx.s
    ctx.add(box(0.12 * s, 0.12 * s, 0.04), "stone", "black" if ctx.colour != "black" else "white")
    if ctx.style == "stacked":
        z = 0.04
        for _ in range(int(ctx.rng.integers(3, 5))):
            r = ctx.u(0.025, 0.045) * s
            ctx.add(ellipsoid(r * 1.2, r, r * 0.8, ctx.u(-0.01, 0.01), 0, z + r * 0.8, count=10))
            z += r * 1.6
        ctx.feature("balanced stones")
    elif ctx.style == "ring":
        R = ctx.u(0.08, 0.11) * s
        ctx.add(torus(R, 0.02, (0, 0, 0.04 + R + 0.02), axis="y", sections=24))
        ctx.feature("a large ring")
    else:
        h = ctx.u(0.25, 0.35) * s
        ctx.add(
            revolve(
                [(0, 0), (0.03, 0), (0.045, h * 0.4), (0.025, h * 0.7), (0.035, h * 0.85), (0, h)], z=0.04, sections=14
            )
        )
        ctx.add(ellipsoid(0.03, 0.03, 0.04, 0, 0, 0.04 + h + 0.03, count=10))
        ctx.feature("a slender figure")


def _pot(ctx: Ctx, r: float, h: float, colour: str) -> None:
    ctx.add(vessel([(r * 0.75, 0), (r, h)], 0.008), "ceramic", colour)
    ctx.add(cyl(r - 0.01, 0.01, 0, 0, h - 0.03, sections=16), "stone", "dark brown")


def _leaves(
    ctx: Ctx, n: int, base: np.ndarray, length: float, colour: str, rise: tuple[float, float] = (0.3, 1.2)
) -> None:
    """Elongated leaves radiating from ``base`` at random azimuths and elevations."""
    for _ in range(n):
        az, el = ctx.u(0, 2 * np.pi), ctx.u(*rise)
        leaf = ellipsoid(length / 2, length * 0.16, 0.008, count=8)
        leaf.apply_transform(_euler(az, el))
        leaf.apply_translation(
            base + length / 2 * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        )
        ctx.add(leaf, "foliage", colour)


def _euler(az: float, el: float) -> np.ndarray:
    """Rotation turning a leaf's long (x) axis to elevation ``el`` and azimuth ``az``."""
    return trimesh.transformations.euler_matrix(0, -el, az, "sxyz")


@category(
    "potted_plant",
    "surface",
    ["living", "office", "kitchen", "bedroom", "bathroom"],
    1.2,
    materials=["foliage"],
    colours=LEAF_COLOURS,
    styles=["leafy", "fern", "flowering"],
)
def potted_plant(ctx: Ctx) -> None:
    potc = ctx.pick(POT_COLOURS)
    r, h = ctx.u(0.07, 0.1) * ctx.s, ctx.u(0.1, 0.15) * ctx.s
    _pot(ctx, r, h, potc)
    n = 14 if ctx.style == "fern" else 9
    _leaves(
        ctx,
        n,
        np.array([0, 0, h - 0.02]),
        ctx.u(0.15, 0.22) * ctx.s,
        ctx.colour,
        (0.1, 0.7) if ctx.style == "fern" else (0.5, 1.3),
    )
    if ctx.style == "flowering":
        fc = ctx.pick(("red", "pink", "white", "yellow", "purple"))
        for x, y in ring_positions(4, 0.05, ctx.u(0, 1)):
            ctx.add(ellipsoid(0.025, 0.025, 0.02, x, y, h + 0.14, count=8), "fabric", fc)
        ctx.feature(f"{fc} blossoms")
    ctx.feature(f"a {potc} pot")


@category("cactus", "surface", ["office", "living", "bedroom"], 0.6, materials=["foliage"], colours=LEAF_COLOURS)
def cactus(ctx: Ctx) -> None:
    potc = ctx.pick(POT_COLOURS)
    r, h = ctx.u(0.05, 0.07), ctx.u(0.07, 0.1)
    _pot(ctx, r, h, potc)
    th = ctx.u(0.12, 0.25) * ctx.s
    ctx.add(
        revolve(
            [(0, 0), (r * 0.6, 0), (r * 0.6, th), (r * 0.3, th + r * 0.4), (0, th + r * 0.5)], z=h - 0.03, sections=12
        )
    )
    n = int(ctx.rng.integers(0, 3))
    for k in range(n):
        sx = 1 if k == 0 else -1
        z0 = h + th * ctx.u(0.3, 0.6)
        ctx.add(rod((0, 0, z0), (sx * r * 1.1, 0, z0), r * 0.25, sections=8))
        ctx.add(rod((sx * r * 1.1, 0, z0), (sx * r * 1.1, 0, z0 + th * 0.35), r * 0.25, sections=8))
    ctx.feature(f"a {potc} pot")
    if n:
        ctx.feature("two arms" if n == 2 else "one arm")


@category(
    "tall_plant",
    "floor",
    ["living", "office", "corridor", "dining"],
    1.0,
    materials=["foliage"],
    colours=LEAF_COLOURS,
    styles=["tree", "palm"],
)
def tall_plant(ctx: Ctx) -> None:
    potc = ctx.pick(POT_COLOURS)
    r, h = ctx.u(0.16, 0.22), ctx.u(0.3, 0.4)
    _pot(ctx, r, h, potc)
    th = ctx.u(1.0, 1.4) * ctx.s
    if ctx.style == "tree":
        ctx.add(rod((0, 0, h - 0.03), (0.03, 0, th), 0.02, sections=8), "wood", "brown")
        for k in range(4):
            c = np.array([ctx.u(-0.15, 0.15), ctx.u(-0.15, 0.15), th - 0.3 + 0.15 * k])
            ctx.add(ellipsoid(ctx.u(0.15, 0.25), ctx.u(0.15, 0.25), ctx.u(0.12, 0.18), *c, count=10))
        ctx.feature("a leafy crown")
    else:
        for _ in range(3):
            top = np.array([ctx.u(-0.08, 0.08), ctx.u(-0.08, 0.08), th * ctx.u(0.7, 1.0)])
            ctx.add(rod((0, 0, h - 0.03), top, 0.012, sections=6), "wood", "olive")
            _leaves(ctx, 5, top, ctx.u(0.35, 0.5), ctx.colour, (-0.4, 0.5))
        ctx.feature("long palm fronds")
    ctx.feature(f"a large {potc} pot")
