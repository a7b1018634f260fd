"""Bathroom fixtures and items. Front faces +y, back (against the wall) at min y."""

from __future__ import annotations

from generators.asset_library.core import Ctx, box, category, cyl, ellipsoid, revolve, rod, torus, vessel

SANITARY_COLOURS = ("white", "white", "white", "cream", "light grey", "black")
TOILETRY_COLOURS = ("white", "pink", "light blue", "green", "yellow", "purple", "teal", "orange")
BATH = ("bathroom",)


def _tap(ctx: Ctx, x: float, y: float, z: float, reach: float) -> None:
    """Chrome tap rising at (x, y, z) and curving forwards (+y) by ``reach``."""
    ctx.add(rod((x, y, z), (x, y, z + 0.14), 0.012), "metal", "silver")
    ctx.add(rod((x, y, z + 0.14), (x, y + reach, z + 0.12), 0.01), "metal", "silver")


@category(
    "toilet", "wall", BATH, 1.0, materials=["ceramic"], colours=SANITARY_COLOURS, styles=["close-coupled", "wall-hung"]
)
def toilet(ctx: Ctx) -> None:
    w, L = ctx.u(0.36, 0.4), ctx.u(0.6, 0.7)
    seat_h = ctx.u(0.4, 0.44)
    if ctx.style == "wall-hung":
        ctx.add(box(w * 1.1, 0.15, 0.8, 0, -L / 2 + 0.075, 0), "plastic", "white")
        ctx.add(box(0.2, 0.01, 0.13, 0, -L / 2 + 0.155, 0.6), "metal", "silver")
        bowl_z = 0.22
        ctx.feature("a flush plate on the wall")
    else:
        ctx.add(box(w * 1.05, 0.18, 0.38, 0, -L / 2 + 0.09, seat_h))
        ctx.add(box(w * 1.1, 0.2, 0.03, 0, -L / 2 + 0.1, seat_h + 0.38))
        ctx.add(cyl(0.015, 0.01, 0, -L / 2 + 0.1, seat_h + 0.41), "metal", "silver")
        ctx.add(revolve([(0, 0), (0.1, 0), (0.12, seat_h * 0.5), (0, seat_h * 0.5)], 0, 0.05, 0, sections=16))
        bowl_z = seat_h * 0.45
        ctx.feature("a cistern")
    bowl = revolve(
        [(0, 0), (0.1, 0), (0.19, seat_h - bowl_z - 0.02), (0.16, seat_h - bowl_z), (0, seat_h - bowl_z - 0.05)],
        sections=20,
    )
    bowl.apply_scale((w / 0.38, 1.25, 1.0))
    bowl.apply_translation((0, 0.06, bowl_z))
    ctx.add(bowl)
    seat = torus(0.16, 0.025, (0, 0, 0), sections=20)
    seat.apply_scale((w / 0.38, 1.25, 0.5))
    seat.apply_translation((0, 0.06, seat_h + 0.01))
    seat_c = ctx.pick(("white", "black", "light brown")) if ctx.colour == "white" else "white"
    ctx.add(seat, "plastic", seat_c)
    ctx.feature(f"a {seat_c} seat")


@category(
    "sink",
    "wall",
    ["bathroom"],
    1.0,
    materials=["ceramic", "stone"],
    colours=SANITARY_COLOURS,
    styles=["pedestal", "vanity"],
)
def sink(ctx: Ctx) -> None:
    w, d = ctx.u(0.5, 0.65) * ctx.s, ctx.u(0.42, 0.5)
    top = ctx.u(0.82, 0.88)
    if ctx.style == "vanity":
        cab = ctx.pick(("white", "light brown", "dark grey", "navy", "brown"))
        ctx.add(box(w, d, top - 0.12), "wood", cab)
        for sx in (-1, 1):
            ctx.add(box(w / 2 - 0.02, 0.02, top - 0.18, sx * w / 4, d / 2, 0.02), "wood", cab)
            ctx.add(
                rod((sx * 0.05, d / 2 + 0.03, top - 0.3), (sx * 0.05, d / 2 + 0.03, top - 0.2), 0.007),
                "metal",
                "silver",
            )
        ctx.add(box(w + 0.02, d + 0.02, 0.12, 0, 0, top - 0.12))
        ctx.feature(f"a {cab} vanity cabinet")
    else:
        ctx.add(
            revolve(
                [(0, 0), (0.12, 0), (0.07, 0.1), (0.08, top - 0.2), (0.14, top - 0.14), (0, top - 0.14)],
                0,
                -0.05,
                0,
                sections=16,
            )
        )
        basin = vessel([(0.12, 0), (w / 2, 0.14)], 0.015, sections=24)
        basin.apply_scale((1.0, d / w, 1.0))
        basin.apply_translation((0, 0, top - 0.14))
        ctx.add(basin)
        ctx.feature("a pedestal")
    _tap(ctx, 0, -d / 2 + 0.06, top, 0.12)
    ctx.feature("a chrome tap")


@category(
    "bathtub",
    "wall",
    BATH,
    0.8,
    materials=["ceramic", "plastic"],
    colours=SANITARY_COLOURS,
    styles=["built-in", "clawfoot"],
)
def bathtub(ctx: Ctx) -> None:
    L, w, h = ctx.u(1.5, 1.8), ctx.u(0.7, 0.8), ctx.u(0.5, 0.6)
    if ctx.style == "clawfoot":
        for sx in (-1, 1):
            for sy in (-1, 1):
                ctx.add(
                    ellipsoid(0.04, 0.04, 0.06, sx * (L / 2 - 0.2), sy * (w / 2 - 0.15), 0.06, count=8), "metal", "gold"
                )
        tub = vessel([(0.25, 0), (0.36, h * 0.6), (0.42, h)], 0.03, sections=24)
        tub.apply_scale((L / 0.84, w / 0.84, 1.0))
        tub.apply_translation((0, 0, 0.08))
        ctx.add(tub)
        ctx.feature("gold claw feet")
    else:
        t = 0.07
        ctx.add(box(L, w, 0.1))
        for sx in (-1, 1):
            ctx.add(box(t, w, h, sx * (L - t) / 2, 0, 0))
        for sy in (-1, 1):
            ctx.add(box(L, t, h, 0, sy * (w - t) / 2, 0))
        ctx.feature("a wide rim")
    _tap(ctx, -L / 2 + 0.1, -w / 2 + 0.04, h + (0.08 if ctx.style == "clawfoot" else 0), 0.1)


@category("towel_rack", "wall_mounted", BATH, 0.7, materials=["metal"], colours=("silver", "black", "gold", "white"))
def towel_rack(ctx: Ctx) -> None:
    w = ctx.u(0.45, 0.7) * ctx.s
    for sx in (-1, 1):
        ctx.add(rod((sx * w / 2, 0, 0.38), (sx * w / 2, 0.012, 0.38), 0.025, sections=12))
        ctx.add(rod((sx * w / 2, 0, 0.38), (sx * w / 2, 0.08, 0.38), 0.01))
    ctx.add(rod((-w / 2, 0.08, 0.38), (w / 2, 0.08, 0.38), 0.01))
    tc = ctx.pick(("white", "light blue", "beige", "pink", "grey", "teal", "yellow"))
    tw = w * 0.75
    ctx.add(box(tw, 0.012, 0.38, 0, 0.066, 0.0), "fabric", tc)
    ctx.add(box(tw, 0.012, 0.3, 0, 0.094, 0.08), "fabric", tc)
    ctx.add(rod((-tw / 2, 0.08, 0.385), (tw / 2, 0.08, 0.385), 0.016, sections=10), "fabric", tc)
    ctx.feature(f"a folded {tc} towel")


@category(
    "toilet_paper",
    "surface",
    BATH,
    0.6,
    materials=["paper"],
    colours=("white", "cream"),
    styles=["single", "stacked"],
    noun="toilet paper",
)
def toilet_paper(ctx: Ctx) -> None:
    n = 1 if ctx.style == "single" else int(ctx.rng.integers(2, 4))
    r, h = ctx.u(0.05, 0.06), ctx.u(0.095, 0.11)
    for k in range(n):
        ctx.add(revolve([(0.02, 0), (r, 0), (r, h), (0.02, h), (0.02, 0)], z=k * h, sections=18))
        ctx.add(torus(0.021, 0.002, (0, 0, k * h + h), sections=12), "paper", "tan")
    ctx.feature(f"{n} rolls stacked" if n > 1 else "a cardboard core")


@category(
    "soap_bottle",
    "surface",
    ["bathroom", "kitchen"],
    0.7,
    materials=["plastic", "glass"],
    colours=TOILETRY_COLOURS,
    styles=["pump", "squeeze"],
)
def soap_bottle(ctx: Ctx) -> None:
    r, h = ctx.u(0.03, 0.04) * ctx.s, ctx.u(0.12, 0.18) * ctx.s
    ctx.add(revolve([(0, 0), (r, 0), (r, h * 0.85), (r * 0.5, h), (0, h)], sections=16))
    if ctx.style == "pump":
        ctx.add(cyl(0.007, 0.04, 0, 0, h), "plastic", "white")
        ctx.add(box(0.02, 0.05, 0.015, 0, 0.015, h + 0.04), "plastic", "white")
        ctx.feature("a pump")
    else:
        ctx.add(cyl(r * 0.6, 0.025, 0, 0, h - 0.005, sections=12), "plastic", "white")
        ctx.feature("a flip cap")
    ctx.add(cyl(r + 0.001, h * 0.35, 0, 0, h * 0.2, sections=16), "paper", "white")


@category(
    "toothbrush_cup",
    "surface",
    BATH,
    0.4,
    materials=["ceramic", "glass", "plastic"],
    colours=TOILETRY_COLOURS + ("white",),
)
def toothbrush_cup(ctx: Ctx) -> None:
    r, h = ctx.u(0.035, 0.045), ctx.u(0.09, 0.12)
    ctx.add(vessel([(r, 0), (r * 1.1, h)], 0.004, sections=16))
    for k, c in enumerate(ctx.rng.permutation(["blue", "pink", "green", "yellow"])[: int(ctx.rng.integers(1, 4))]):
        x = (k - 1) * 0.012
        ctx.add(rod((x, 0, 0.01), (x * 3, 0.01, h + 0.1), 0.005, sections=6), "plastic", str(c))
        ctx.add(box(0.012, 0.008, 0.025, x * 3, 0.015, h + 0.075), "plastic", "white")
    ctx.feature("toothbrushes")
