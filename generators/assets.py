"""Procedural object library: sample parametric, textured, described assets by category.

Each category (``generators/asset_library/*.py``) is a builder over trimesh primitives with sampled
proportions, parts and styles; :func:`sample_asset` picks the attributes (colour, material, size
class, style), builds the meshes, moves them into the object frame (metres, z up, base at z = 0,
footprint centred, front facing +y, back at min y) and writes a short natural description.

Identical copies: reuse one :class:`Asset`. Near-duplicates: call :func:`sample_asset` for the same
category with the first one's colour, material, size (and style) forced; only continuous
proportions, the exact shade and texture seeds then change (a few percent).
"""

from __future__ import annotations

import re

import numpy as np

from generators.asset_library import (  # noqa: F401  (imports register the categories)
    bathroom,
    decor,
    electronics,
    furniture,
    kitchen,
    leisure,
    office,
)
from generators.asset_library.core import (
    PLACEMENTS,
    RECIPES,
    ROOM_KINDS,
    SIZES,
    Asset,
    CategorySpec,
    Ctx,
    Part,
    size_scale,
)
from generators.materials import COLOURS, MATERIALS
from openreloc_bench.errors import ConfigError

__all__ = [
    "Asset",
    "CATEGORIES",
    "CategorySpec",
    "Part",
    "categories_for_room",
    "sample_asset",
    "PLACEMENTS",
    "ROOM_KINDS",
    "SIZES",
]

CATEGORIES: dict[str, CategorySpec] = {name: r.spec for name, r in sorted(RECIPES.items())}
"""Every category by name."""

_SIZE_P = (0.3, 0.45, 0.25)
_SIZE_WORD = {"small": "small", "medium": "", "large": "large"}
_MATERIAL_ADJ = {"wood": "wooden"}
_UNSAID_MATERIALS = ("foliage",)  # "a leafy cactus made of leaves": say nothing about these
_TEMPLATES = (
    "{a} {size} {colour} {noun}{feat}",
    "{a} {colour} {mat} {noun}{feat}",
    "{a} {size} {mat} {noun} in {colour}{feat}",
    "{a} {colour} {style} {noun}",
    "{a} {colour} {noun} made of {matn}{feat}",
    "{a} {size} {style} {noun} in {colour}",
)


def _check_choice(key: str, value: str | None, known) -> None:
    if value is not None and value not in known:
        raise ConfigError(f"unknown {key} '{value}' (known: {', '.join(known)})")


def sample_asset(
    category: str,
    rng: np.random.Generator,
    colour: str | None = None,
    material: str | None = None,
    size: str | None = None,
    style: str | None = None,
) -> Asset:
    """Sample one instance of ``category``; deterministic in the rng state.

    ``colour`` / ``material`` / ``size`` / ``style`` force that attribute (near-duplicates); the
    random draws happen in the same order whether or not an attribute is forced.
    """
    recipe = RECIPES.get(category)
    if recipe is None:
        raise ConfigError(f"unknown asset category '{category}' (known: {', '.join(CATEGORIES)})")
    _check_choice("colour", colour, tuple(COLOURS))
    _check_choice("material", material, MATERIALS)
    _check_choice("size", size, SIZES)
    _check_choice(f"style for '{category}'", style, recipe.styles)
    drawn_colour = recipe.colours[int(rng.integers(len(recipe.colours)))]
    drawn_material = recipe.materials[int(rng.integers(len(recipe.materials)))]
    drawn_size = SIZES[int(rng.choice(len(SIZES), p=_SIZE_P))]
    drawn_style = recipe.styles[int(rng.integers(len(recipe.styles)))]
    shade = rng.uniform(0.94, 1.06)
    colour, material = colour or drawn_colour, material or drawn_material
    size, style = size or drawn_size, style or drawn_style
    main_rgb = tuple(float(c) for c in np.clip(np.asarray(COLOURS[colour]) * shade, 0.0, 1.0))
    ctx = Ctx(rng, colour, material, size, style, size_scale(size, rng), main_rgb)
    recipe.build(ctx)
    parts = ctx.parts()
    lo = np.min([p.mesh.bounds[0] for p in parts], axis=0)
    hi = np.max([p.mesh.bounds[1] for p in parts], axis=0)
    shift = -np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    for p in parts:
        p.mesh.apply_translation(shift)
    attributes = {"colour": colour, "material": material, "size": size, "style": style}
    return Asset(
        category=category,
        parts=parts,
        attributes=attributes,
        description=_describe(recipe.noun, attributes, ctx.features, rng),
        placement=recipe.spec.placement,
        surface_heights=sorted(float(h + shift[2]) for h in ctx.surface_heights),
    )


def _describe(noun: str, attributes: dict[str, str], features: list[str], rng: np.random.Generator) -> str:
    """Short natural phrase from a randomly chosen template (rng-deterministic)."""
    templates = _TEMPLATES
    if attributes["material"] in _UNSAID_MATERIALS:
        templates = tuple(t for t in _TEMPLATES if "{mat" not in t)
    template = templates[int(rng.integers(len(templates)))]
    n_feat = min(len(features), int(rng.integers(0, 3)) if "{feat}" in template else 0)
    chosen = [features[i] for i in sorted(rng.choice(len(features), size=n_feat, replace=False))] if n_feat else []
    mat = attributes["material"]
    text = template.format(
        a="{a}",
        size=_SIZE_WORD[attributes["size"]],
        colour=attributes["colour"],
        noun=noun,
        mat=_MATERIAL_ADJ.get(mat, mat),
        matn=mat,
        style="" if attributes["style"] == "standard" else attributes["style"],
        feat=(" with " + " and ".join(chosen)) if chosen else "",
    )
    text = re.sub(r"\ba ([aeiou])", r"an \1", " ".join(text.split()).replace("{a}", "a"))
    return text


def categories_for_room(room_kind: str, placement: str | None = None) -> list[CategorySpec]:
    """Categories that appear in ``room_kind`` (optionally only one placement), sorted by name."""
    _check_choice("room kind", room_kind, ROOM_KINDS)
    _check_choice("placement", placement, PLACEMENTS)
    return [s for s in CATEGORIES.values() if room_kind in s.rooms and (placement is None or s.placement == placement)]
