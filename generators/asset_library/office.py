"""Office items and general household storage. Front faces +y, back at min y."""

from __future__ import annotations

import numpy as np

from generators.asset_library.core import Ctx, box, category, cyl, ellipsoid, revolve, rod, rotated, torus, vessel
from generators.asset_library.furniture import BOOK_COLOURS

OFFICE_COLOURS = ("black", "grey", "white", "blue", "red", "green", "light grey", "navy")


@category(
    "filing_cabinet",
    "wall",
    ["office"],
    0.8,
    materials=["metal"],
    colours=("grey", "light grey", "black", "white", "dark grey", "blue"),
    styles=["two-drawer", "four-drawer"],
)
def filing_cabinet(ctx: Ctx) -> None:
    n = 2 if ctx.style == "two-drawer" else 4
    w, d = ctx.u(0.4, 0.48), ctx.u(0.55, 0.65)
    h = n * ctx.u(0.3, 0.34) + 0.04
    ctx.add(box(w, d, h))
    dh = (h - 0.04) / n
    for i in range(n):
        z = 0.03 + i * dh
        ctx.add(box(w - 0.03, 0.015, dh - 0.02, 0, d / 2, z))
        ctx.add(rod((-0.07, d / 2 + 0.03, z + dh * 0.7), (0.07, d / 2 + 0.03, z + dh * 0.7), 0.008), "metal", "silver")
        ctx.add(box(0.08, 0.004, 0.03, 0, d / 2 + 0.015, z + dh * 0.82), "paper", "white")
    ctx.feature(f"{'two' if n == 2 else 'four'} drawers with labels")
    ctx.surface_heights.append(h)


@category("whiteboard", "wall_mounted", ["office"], 0.6, materials=["plastic"], colours=("white",))
def whiteboard(ctx: Ctx) -> None:
    w, h = ctx.u(0.9, 1.5) * ctx.s, ctx.u(0.6, 1.0) * ctx.s
    ctx.add(box(w, 0.015, h, 0, 0, 0.04))
    for z in (0.04, 0.04 + h):
        ctx.add(box(w + 0.02, 0.02, 0.02, 0, 0.002, z - 0.01), "metal", "silver")
    for sx in (-1, 1):
        ctx.add(box(0.02, 0.02, h, sx * (w / 2 + 0.0), 0.002, 0.04), "metal", "silver")
    ctx.add(box(w * 0.4, 0.06, 0.02, 0, 0.03, 0.0), "metal", "silver")
    for k, c in enumerate(("black", "blue", "red")):
        ctx.add(
            rod((-0.1 + k * 0.06, 0.04, 0.03), (-0.1 + k * 0.06 + 0.04, 0.04, 0.03), 0.007, sections=6), "plastic", c
        )
    if ctx.chance(0.6):
        for k in range(3):
            ctx.add(
                box(
                    w * ctx.u(0.2, 0.6), 0.002, 0.012, ctx.u(-w * 0.15, w * 0.15), 0.0085, 0.04 + h * (0.75 - 0.15 * k)
                ),
                "plastic",
                ctx.pick(("black", "blue", "red")),
            )
        ctx.feature("writing on it")
    ctx.feature("a marker tray")


@category(
    "book_stack",
    "surface",
    ["office", "living", "bedroom"],
    1.5,
    materials=["paper"],
    colours=BOOK_COLOURS,
    noun="stack of books",
)
def book_stack(ctx: Ctx) -> None:
    n = int(ctx.rng.integers(2, 7))
    z = 0.0
    for i in range(n):
        w, d, t = ctx.u(0.14, 0.24) * ctx.s, ctx.u(0.2, 0.3) * ctx.s, ctx.u(0.02, 0.05)
        b = box(w, d, t, ctx.u(-0.01, 0.01), ctx.u(-0.01, 0.01), z)
        ctx.add(rotated(b, ctx.u(-0.25, 0.25), (0, 0, 1)), None, None if i == 0 else ctx.pick(BOOK_COLOURS))
        ctx.add(box(w * 0.97, d * 0.97, t * 0.8, b.centroid[0] + 0.004, b.centroid[1], z + t * 0.1), "paper", "cream")
        z += t
    ctx.feature(f"{n} books")


@category(
    "binder",
    "surface",
    ["office"],
    0.6,
    materials=["plastic", "paper"],
    colours=OFFICE_COLOURS + ("yellow",),
    noun="row of binders",
)
def binder(ctx: Ctx) -> None:
    n = int(ctx.rng.integers(1, 6))
    h, d = ctx.u(0.29, 0.32), ctx.u(0.26, 0.29)
    for i in range(n):
        t = ctx.u(0.045, 0.08)
        x = i * 0.085
        col = None if i == 0 or ctx.chance(0.5) else ctx.pick(OFFICE_COLOURS)
        ctx.add(box(t, d, h, x), None, col)
        ctx.add(box(t * 0.6, 0.004, 0.08, x, d / 2, h * 0.6), "paper", "white")
        ctx.add(torus(0.014, 0.004, (x, d / 2 + 0.002, h * 0.25), axis="y", sections=10), "metal", "silver")
    ctx.feature("white spine labels" if n > 1 else "a white spine label")


@category(
    "desk_organiser",
    "surface",
    ["office"],
    0.5,
    materials=["plastic", "metal", "wood"],
    colours=("black", "white", "silver", "light brown", "grey"),
    noun="desk organiser",
)
def desk_organiser(ctx: Ctx) -> None:
    w, d = ctx.u(0.18, 0.26) * ctx.s, ctx.u(0.1, 0.14)
    ctx.add(box(w, d, 0.02))
    ctx.add(vessel([(0.035, 0), (0.035, 0.1)], 0.003, -w / 2 + 0.045, 0, 0.02, sections=14))
    for _ in range(int(ctx.rng.integers(3, 6))):
        top = (-w / 2 + 0.045 + ctx.u(-0.025, 0.025), ctx.u(-0.025, 0.025), 0.16 + ctx.u(0, 0.03))
        ctx.add(
            rod((-w / 2 + 0.045, 0, 0.03), top, 0.004, sections=6),
            "plastic",
            ctx.pick(("blue", "red", "black", "yellow", "green")),
        )
    ctx.add(box(w * 0.45, d - 0.01, 0.05, w * 0.22, 0, 0.02))
    ctx.add(box(w * 0.4, d * 0.7, 0.035, w * 0.22, 0, 0.03), "paper", "yellow")
    ctx.feature("pens and sticky notes")


@category("globe", "surface", ["office", "living"], 0.2, materials=["paper"], colours=("light blue", "blue", "cream"))
def globe(ctx: Ctx) -> None:
    r = ctx.u(0.1, 0.15) * ctx.s
    ctx.add(cyl(0.08, 0.02, sections=16), "wood", "dark brown")
    ctx.add(cyl(0.012, r * 0.5, 0, 0, 0.02), "wood", "dark brown")
    c = (0, 0, 0.02 + r * 0.5 + r + 0.02)
    ctx.add(ellipsoid(r, r, r, *c, count=16))
    for _ in range(3):
        a = ctx.u(0, 2 * np.pi)
        ctx.add(
            ellipsoid(
                r * 0.45,
                r * 0.35,
                r * 0.35,
                c[0] + r * 0.75 * np.cos(a),
                c[1] + r * 0.75 * np.sin(a),
                c[2] + ctx.u(-r * 0.4, r * 0.4),
                count=8,
            ),
            "paper",
            ctx.pick(("green", "tan", "olive")),
        )
    ctx.add(rotated(torus(r + 0.015, 0.005, c, axis="x", sections=20), 0.4, (1, 0, 0), c), "metal", "gold")
    ctx.feature("a brass meridian")


@category(
    "trash_can",
    "floor",
    ["kitchen", "office", "bathroom", "bedroom"],
    1.2,
    materials=["metal", "plastic"],
    colours=("silver", "black", "white", "grey", "green", "red", "blue"),
    styles=["pedal", "open", "swing-lid"],
)
def trash_can(ctx: Ctx) -> None:
    r, h = ctx.u(0.12, 0.17) * ctx.s, ctx.u(0.3, 0.45) * ctx.s
    if ctx.style == "open":
        ctx.add(vessel([(r * 0.8, 0), (r, h)], 0.004, sections=20))
        ctx.add(torus(r, 0.006, (0, 0, h), sections=20))
        ctx.feature("an open top")
        return
    ctx.add(cyl(r, h, sections=20))
    lid_c = "silver" if ctx.colour != "silver" else "black"
    if ctx.style == "pedal":
        ctx.add(revolve([(0, 0), (r + 0.004, 0), (r * 0.8, 0.03), (0, 0.035)], z=h, sections=20), "metal", lid_c)
        ctx.add(box(0.08, 0.06, 0.015, 0, r + 0.02, 0.02), "metal", lid_c)
        ctx.feature("a foot pedal")
    else:
        ctx.add(
            revolve([(0, 0), (r + 0.004, 0), (r, 0.05), (r * 0.5, 0.1), (0, 0.11)], z=h, sections=20), "plastic", lid_c
        )
        ctx.add(box(r * 1.2, 0.01, 0.05, 0, r * 0.4, h + 0.04), "plastic", "black")
        ctx.feature("a swing lid")


@category(
    "laundry_basket",
    "floor",
    ["bedroom", "bathroom"],
    0.5,
    materials=["plastic", "fabric", "wood"],
    colours=("white", "grey", "beige", "light blue", "tan"),
)
def laundry_basket(ctx: Ctx) -> None:
    w, d, h = ctx.u(0.4, 0.55) * ctx.s, ctx.u(0.3, 0.4) * ctx.s, ctx.u(0.3, 0.5)
    t = 0.012
    ctx.add(box(w, d, t))
    for sx in (-1, 1):
        ctx.add(box(t, d, h, sx * (w - t) / 2, 0, 0))
        for k in range(3):
            ctx.add(
                box(t * 1.5, d * 0.7, 0.04, sx * (w - t) / 2, 0, h * (0.25 + 0.22 * k)),
                None,
                "dark grey" if ctx.colour == "white" else "white",
            )
    for sy in (-1, 1):
        ctx.add(box(w, t, h, 0, sy * (d - t) / 2, 0))
    c = ctx.pick(("blue", "white", "pink", "red", "grey"))
    ctx.add(ellipsoid(w * 0.4, d * 0.35, 0.06, 0, 0, h - 0.02, count=10), "fabric", c)
    ctx.feature(f"{c} clothes piled in it")


@category("fire_extinguisher", "floor", ["kitchen", "corridor", "office"], 0.3, materials=["metal"], colours=("red",))
def fire_extinguisher(ctx: Ctx) -> None:
    r, h = ctx.u(0.06, 0.08) * ctx.s, ctx.u(0.4, 0.55) * ctx.s
    ctx.add(revolve([(0, 0), (r, 0), (r, h), (r * 0.5, h + r * 0.6), (0, h + r * 0.65)], sections=16))
    top = h + r * 0.6
    ctx.add(cyl(0.015, 0.05, 0, 0, top), "metal", "black")
    ctx.add(box(0.12, 0.02, 0.015, 0.03, 0, top + 0.05), "metal", "black")
    ctx.add(rod((0, 0, top + 0.03), (r + 0.03, 0.01, top - 0.05), 0.008), "rubber", "black")
    ctx.add(rod((r + 0.03, 0.01, top - 0.05), (r + 0.02, 0.02, h * 0.4), 0.008), "rubber", "black")
    ctx.add(cyl(r + 0.001, h * 0.3, 0, 0, h * 0.35, sections=16), "paper", "white")
    ctx.feature("a black hose")
