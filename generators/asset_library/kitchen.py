"""Kitchen appliances and kitchenware. Front faces +y, back at min y."""

from __future__ import annotations

import numpy as np

from generators.asset_library.core import (
    Ctx,
    box,
    category,
    cyl,
    ellipsoid,
    revolve,
    ring_positions,
    rod,
    torus,
    vessel,
)

APPLIANCE_COLOURS = ("white", "white", "silver", "black", "cream", "dark grey")
CROCKERY_COLOURS = (
    "white",
    "white",
    "cream",
    "blue",
    "red",
    "green",
    "yellow",
    "black",
    "grey",
    "teal",
    "pink",
    "orange",
)
KITCHEN = ("kitchen",)


def _handle_bar(ctx: Ctx, p0: tuple, p1: tuple, out: float = 0.04, colour: str = "silver") -> None:
    """Bar handle standing ``out`` in front (+y) of the points p0, p1."""
    a, b = np.array(p0, float), np.array(p1, float)
    ctx.add(rod(a + (0, out, 0), b + (0, out, 0), 0.01), "metal", colour)
    ctx.add(rod(a, a + (0, out, 0), 0.007), "metal", colour)
    ctx.add(rod(b, b + (0, out, 0), 0.007), "metal", colour)


@category(
    "fridge",
    "wall",
    KITCHEN,
    1.2,
    materials=["metal", "plastic"],
    colours=APPLIANCE_COLOURS + ("red", "light blue"),
    styles=["bottom-freezer", "side-by-side", "retro"],
)
def fridge(ctx: Ctx) -> None:
    side = ctx.style == "side-by-side"
    w = ctx.u(0.85, 0.95) if side else ctx.u(0.58, 0.7) * ctx.s
    d, h = ctx.u(0.62, 0.72), ctx.u(1.7, 1.9) if ctx.style != "retro" else ctx.u(1.45, 1.6)
    ctx.add(box(w, d - 0.05, h, 0, -0.025, 0))
    if side:
        for sx in (-1, 1):
            ctx.add(box(w / 2 - 0.01, 0.05, h - 0.02, sx * w / 4, d / 2 - 0.05, 0.01))
            _handle_bar(ctx, (-sx * 0.05, d / 2, h * 0.35), (-sx * 0.05, d / 2, h * 0.75))
        ctx.add(box(0.22, 0.01, 0.3, -w / 4, d / 2, h * 0.55), "plastic", "dark grey")
        ctx.feature("two tall doors and a water dispenser")
        return
    split = h * ctx.u(0.32, 0.38)
    ctx.add(box(w - 0.01, 0.05, split - 0.02, 0, d / 2 - 0.05, 0.01))
    ctx.add(box(w - 0.01, 0.05, h - split - 0.02, 0, d / 2 - 0.05, split + 0.01))
    hx = w / 2 - 0.06
    _handle_bar(ctx, (hx, d / 2, split - 0.25), (hx, d / 2, split - 0.05))
    _handle_bar(ctx, (hx, d / 2, split + 0.1), (hx, d / 2, split + 0.45))
    ctx.feature("a freezer drawer" if ctx.style == "bottom-freezer" else "rounded retro styling")
    ctx.feature("chrome handles")


@category("oven", "wall", KITCHEN, 0.9, materials=["metal"], colours=APPLIANCE_COLOURS, styles=["gas", "electric"])
def oven(ctx: Ctx) -> None:
    w, d, h = ctx.u(0.58, 0.62) * ctx.s**0.5, ctx.u(0.58, 0.62), ctx.u(0.85, 0.92)
    ctx.add(box(w, d, h))
    ctx.add(box(w - 0.08, 0.012, h * 0.45, 0, d / 2, 0.12), "glass", "black")
    _handle_bar(ctx, (-w / 2 + 0.06, d / 2, 0.12 + h * 0.48), (w / 2 - 0.06, d / 2, 0.12 + h * 0.48))
    for x in np.linspace(-w / 2 + 0.08, w / 2 - 0.08, 5):
        ctx.add(rod((x, d / 2, h - 0.07), (x, d / 2 + 0.025, h - 0.07), 0.016), "plastic", "black")
    ctx.add(box(w, 0.04, 0.12, 0, -d / 2 + 0.02, h), None, None)
    for sx in (-1, 1):
        for sy in (-1, 1):
            r = 0.07 if sx * sy > 0 else 0.055
            if ctx.style == "gas":
                ctx.add(cyl(r * 0.6, 0.015, sx * w / 4, sy * d / 4, h), "metal", "black")
                ctx.add(torus(r, 0.006, (sx * w / 4, sy * d / 4, h + 0.02)), "metal", "black")
            else:
                ctx.add(cyl(r, 0.006, sx * w / 4, sy * d / 4, h, sections=20), "ceramic", "black")
    ctx.feature("four burners" if ctx.style == "gas" else "a ceramic hob")
    ctx.feature("a glass oven door")


@category("microwave", "surface", KITCHEN, 1.0, materials=["metal", "plastic"], colours=APPLIANCE_COLOURS)
def microwave(ctx: Ctx) -> None:
    w, d, h = ctx.u(0.44, 0.52) * ctx.s, ctx.u(0.34, 0.4) * ctx.s, ctx.u(0.26, 0.31) * ctx.s
    ctx.add(box(w, d, h, 0, 0, 0.01))
    for x, y in (
        (-w / 2 + 0.04, -d / 2 + 0.04),
        (w / 2 - 0.04, -d / 2 + 0.04),
        (-w / 2 + 0.04, d / 2 - 0.04),
        (w / 2 - 0.04, d / 2 - 0.04),
    ):
        ctx.add(cyl(0.012, 0.01, x, y, 0), "rubber", "black")
    ctx.add(box(w * 0.62, 0.01, h * 0.7, -w * 0.14, d / 2, 0.01 + h * 0.15), "glass", "black")
    ctx.add(box(w * 0.2, 0.008, h * 0.7, w * 0.36, d / 2, 0.01 + h * 0.15), "plastic", "dark grey")
    ctx.add(
        rod((w * 0.36, d / 2, 0.01 + h * 0.35), (w * 0.36, d / 2 + 0.02, 0.01 + h * 0.35), 0.02), "plastic", "silver"
    )
    ctx.feature("a dark glass door")
    ctx.feature("a control panel")
    ctx.surface_heights.append(h + 0.01)


@category(
    "washing_machine",
    "wall",
    ["bathroom", "kitchen"],
    0.7,
    materials=["metal", "plastic"],
    colours=("white", "white", "silver", "dark grey"),
)
def washing_machine(ctx: Ctx) -> None:
    w, d, h = ctx.u(0.58, 0.62), ctx.u(0.55, 0.62), ctx.u(0.82, 0.88)
    ctx.add(box(w, d, h))
    door_z, door_r = h * 0.48, w * ctx.u(0.3, 0.34)
    ctx.add(torus(door_r, 0.03, (0, d / 2 + 0.01, door_z), axis="y", sections=20), "plastic", "silver")
    ctx.add(rod((0, d / 2 - 0.01, door_z), (0, d / 2 + 0.02, door_z), door_r, sections=20), "glass", "dark grey")
    ctx.add(box(w * 0.35, 0.01, 0.08, -w * 0.25, d / 2, h - 0.12), "plastic", "light grey")
    ctx.add(rod((w * 0.25, d / 2, h - 0.08), (w * 0.25, d / 2 + 0.03, h - 0.08), 0.03), "plastic", "silver")
    ctx.feature("a round porthole door")
    ctx.surface_heights.append(h)


@category(
    "kettle",
    "surface",
    KITCHEN,
    1.0,
    materials=["metal", "plastic"],
    colours=("silver", "white", "black", "red", "cream", "light blue"),
    styles=["jug", "stovetop"],
)
def kettle(ctx: Ctx) -> None:
    r, h = ctx.u(0.07, 0.09) * ctx.s, ctx.u(0.18, 0.24) * ctx.s
    if ctx.style == "jug":
        ctx.add(cyl(r + 0.015, 0.02), "plastic", "black")
        ctx.add(revolve([(0, 0), (r, 0), (r * 0.95, h), (0, h)], z=0.02))
        ctx.add(rod((0, -r * 0.9, 0.06), (0, -r - 0.05, 0.08), 0.012), "plastic", "black")
        ctx.add(rod((0, -r - 0.05, 0.08), (0, -r - 0.05, h - 0.02), 0.014), "plastic", "black")
        ctx.add(rod((0, -r - 0.05, h - 0.02), (0, -r * 0.8, h), 0.012), "plastic", "black")
        ctx.add(box(0.05, 0.04, 0.04, 0, r - 0.01, h - 0.04))
        ctx.feature("a black handle")
    else:
        ctx.add(
            revolve([(0, 0), (r * 1.3, 0), (r * 1.35, h * 0.3), (r * 0.6, h * 0.75), (0.03, h * 0.8), (0, h * 0.8)])
        )
        ctx.add(rod((0, r, h * 0.25), (0, r * 1.9, h * 0.7), 0.014))
        ctx.add(torus(r * 0.7, 0.01, (0, 0, h * 0.95), axis="y"), "plastic", "black")
        ctx.feature("a curved spout")


@category(
    "toaster",
    "surface",
    KITCHEN,
    0.8,
    materials=["metal", "plastic"],
    colours=("silver", "white", "red", "black", "cream", "light blue"),
)
def toaster(ctx: Ctx) -> None:
    w, d, h = ctx.u(0.26, 0.32) * ctx.s, ctx.u(0.15, 0.19), ctx.u(0.18, 0.21)
    ctx.add(box(w, d, h))
    for y in (-d / 5, d / 5):
        ctx.add(box(w * 0.75, 0.025, 0.004, 0, y, h), "metal", "black")
    ctx.add(box(0.03, 0.02, 0.015, w / 2 + 0.01, 0, h * 0.6), "plastic", "black")
    ctx.add(box(0.012, 0.05, 0.1, w / 2 + 0.006, 0, h * 0.3), "plastic", "dark grey")
    ctx.feature("two bread slots")


@category(
    "coffee_maker", "surface", KITCHEN, 0.5, materials=["plastic", "metal"], colours=("black", "silver", "white", "red")
)
def coffee_maker(ctx: Ctx) -> None:
    w, d, h = ctx.u(0.2, 0.25) * ctx.s, ctx.u(0.24, 0.3), ctx.u(0.32, 0.38)
    ctx.add(box(w, d, 0.04))
    ctx.add(box(w, d * 0.4, h, 0, -d * 0.3, 0))
    ctx.add(box(w, d, 0.08, 0, 0, h - 0.08))
    ctx.add(vessel([(0.065, 0), (0.07, 0.1), (0.06, 0.15)], 0.004, 0, d * 0.15, 0.04), "glass", "dark grey")
    ctx.add(cyl(0.05, 0.04, 0, d * 0.15, 0.1), "plastic", "dark brown")
    ctx.feature("a glass carafe")


@category(
    "mug",
    "surface",
    ["kitchen", "office", "dining", "living"],
    2.0,
    materials=["ceramic", "ceramic", "metal"],
    colours=CROCKERY_COLOURS,
)
def mug(ctx: Ctx) -> None:
    r, h = ctx.u(0.038, 0.046) * ctx.s, ctx.u(0.085, 0.105) * ctx.s
    ctx.add(vessel([(r * 0.9, 0), (r, 0.01), (r, h)], 0.005))
    ctx.add(torus(h * 0.28, 0.007, (r + h * 0.18, 0, h * 0.5), axis="y", sections=12))
    ctx.feature("a round handle")


@category(
    "bowl", "surface", ["kitchen", "dining"], 1.5, materials=["ceramic", "wood", "glass"], colours=CROCKERY_COLOURS
)
def bowl(ctx: Ctx) -> None:
    r, h = ctx.u(0.07, 0.11) * ctx.s, ctx.u(0.05, 0.08) * ctx.s
    ctx.add(vessel([(r * 0.45, 0), (r * 0.8, h * 0.4), (r, h)], 0.005, sections=24))


@category(
    "plate_stack",
    "surface",
    ["kitchen", "dining"],
    1.0,
    materials=["ceramic"],
    colours=CROCKERY_COLOURS,
    noun="stack of plates",
)
def plate_stack(ctx: Ctx) -> None:
    r, n = ctx.u(0.1, 0.14) * ctx.s, int(ctx.rng.integers(3, 9))
    for i in range(n):
        ctx.add(revolve([(0, 0), (r * 0.6, 0), (r, 0.016), (r * 0.95, 0.02), (0, 0.012)], z=i * 0.018, sections=24))
    ctx.feature(f"{n} plates")


@category(
    "bottle",
    "surface",
    ["kitchen", "dining", "living"],
    1.5,
    materials=["glass", "plastic"],
    colours=("green", "dark green", "light blue", "white", "brown", "dark red"),
    styles=["wine", "water", "milk"],
)
def bottle(ctx: Ctx) -> None:
    if ctx.style == "wine":
        r, h = 0.037, ctx.u(0.28, 0.32)
        prof = [(0, 0), (r, 0), (r, h * 0.62), (0.014, h * 0.78), (0.013, h), (0, h)]
    elif ctx.style == "water":
        r, h = ctx.u(0.03, 0.04), ctx.u(0.2, 0.28)
        prof = [(0, 0), (r, 0), (r * 0.9, h * 0.4), (r, h * 0.7), (0.014, h * 0.9), (0.014, h), (0, h)]
    else:
        r, h = 0.045, ctx.u(0.22, 0.26)
        prof = [(0, 0), (r, 0), (r, h * 0.7), (0.02, h * 0.9), (0.02, h), (0, h)]
    ctx.add(revolve([(a * ctx.s, b * ctx.s) for a, b in prof]))
    cap = ctx.pick(("red", "white", "black", "blue", "gold"))
    ctx.add(cyl(0.016 * ctx.s, 0.025, 0, 0, h * ctx.s - 0.01, sections=12), "plastic", cap)
    ctx.add(
        cyl(r * ctx.s + 0.001, h * 0.25 * ctx.s, 0, 0, h * 0.2 * ctx.s, sections=20),
        "paper",
        ctx.pick(("white", "cream", "yellow")),
    )
    ctx.feature("a paper label")
    ctx.feature(f"a {cap} cap")


@category(
    "pot",
    "surface",
    KITCHEN,
    0.8,
    materials=["metal", "metal", "ceramic"],
    colours=("silver", "black", "red", "dark grey", "orange", "teal"),
    noun="cooking pot",
)
def pot(ctx: Ctx) -> None:
    r, h = ctx.u(0.09, 0.13) * ctx.s, ctx.u(0.1, 0.16) * ctx.s
    ctx.add(vessel([(r, 0), (r, h)], 0.004, sections=24))
    ctx.add(revolve([(0, 0), (r + 0.005, 0), (r * 0.6, 0.025), (0, 0.03)], z=h, sections=24))
    ctx.add(ellipsoid(0.018, 0.018, 0.012, 0, 0, h + 0.035, count=8), "plastic", "black")
    for sx in (-1, 1):
        ctx.add(torus(0.025, 0.006, (sx * (r + 0.015), 0, h * 0.8), axis="z", sections=10), "metal", "black")
    ctx.feature("a lid and two side handles")


@category(
    "pan",
    "surface",
    KITCHEN,
    0.6,
    materials=["metal"],
    colours=("black", "dark grey", "silver", "red"),
    noun="frying pan",
)
def pan(ctx: Ctx) -> None:
    r = ctx.u(0.1, 0.14) * ctx.s
    ctx.add(vessel([(r * 0.85, 0), (r, 0.05)], 0.004, sections=24))
    ctx.add(rod((r * 0.95, 0, 0.04), (r + 0.2 * ctx.s, 0, 0.06), 0.011), "plastic", "black")
    ctx.feature("a long black handle")


@category(
    "fruit_bowl",
    "surface",
    ["kitchen", "dining", "living"],
    0.8,
    materials=["ceramic", "wood", "metal"],
    colours=CROCKERY_COLOURS + ("light brown",),
    noun="fruit bowl",
)
def fruit_bowl(ctx: Ctx) -> None:
    r, h = ctx.u(0.12, 0.16) * ctx.s, ctx.u(0.06, 0.09)
    ctx.add(vessel([(r * 0.5, 0), (r, h)], 0.006, sections=24))
    kinds = ctx.rng.permutation(["apples", "oranges", "lemons"])[: int(ctx.rng.integers(1, 3))]
    colour_of = {"apples": ("red", 0.037), "oranges": ("orange", 0.038), "lemons": ("yellow", 0.03)}
    n = int(ctx.rng.integers(4, 7))
    for i, (x, y) in enumerate(ring_positions(n, r * 0.5, ctx.u(0, 1))):
        col, rad = colour_of[kinds[i % len(kinds)]]
        ctx.add(ellipsoid(rad, rad, rad * 0.95, x, y, 0.02 + rad, count=10), "plastic", col)
    ctx.add(ellipsoid(0.035, 0.035, 0.034, 0, 0, 0.05 + 0.035, count=10), "plastic", colour_of[kinds[0]][0])
    ctx.feature(" and ".join(kinds))


@category(
    "teapot", "surface", ["kitchen", "dining", "living"], 0.4, materials=["ceramic", "metal"], colours=CROCKERY_COLOURS
)
def teapot(ctx: Ctx) -> None:
    r = ctx.u(0.07, 0.09) * ctx.s
    ctx.add(revolve([(0, 0), (r * 0.7, 0), (r, r * 0.6), (r * 0.85, r * 1.2), (r * 0.45, r * 1.4), (0, r * 1.4)]))
    ctx.add(ellipsoid(0.02, 0.02, 0.02, 0, 0, r * 1.45, count=8))
    ctx.add(rod((r * 0.8, 0, r * 0.5), (r * 1.6, 0, r * 1.25), 0.013))
    ctx.add(torus(r * 0.45, 0.01, (-r * 1.05, 0, r * 0.75), axis="y", sections=12))
    ctx.feature("a spout")


@category(
    "wine_glass",
    "surface",
    ["dining", "kitchen"],
    0.5,
    materials=["glass"],
    colours=("light blue", "white", "light grey"),
)
def wine_glass(ctx: Ctx) -> None:
    s = ctx.s
    stem = 0.1 * s
    ctx.add(
        revolve([(0, 0), (0.035 * s, 0), (0.035 * s, 0.004), (0.005, 0.012), (0.005, stem), (0, stem)], sections=16)
    )
    ctx.add(
        vessel(
            [(0.006, 0), (0.03 * s, 0.03 * s), (0.037 * s, 0.07 * s), (0.032 * s, 0.11 * s)],
            0.002,
            z=stem - 0.002,
            sections=16,
        )
    )
    ctx.feature("a thin stem")
