"""Data types, mesh primitives and the category registry shared by the asset-library modules.

Object frame of every asset: metres, z up, base at z = 0, bounding-box footprint centred on
x = y = 0, **front facing +y** (so the back, which goes against a wall, is the min-y side).
Category modules build meshes from trimesh primitives through a :class:`Ctx`, which groups them
into one :class:`Part` per (material, colour) so a renderer gets few geoms per object.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import trimesh
from trimesh import creation

from generators.materials import COLOURS, MATERIALS

PLACEMENTS: tuple[str, ...] = ("floor", "wall", "surface", "ceiling", "wall_mounted")
"""floor: stands free; wall: stands with its back (min y) against a wall; surface: goes on tables
and shelves; ceiling: hangs with its top (z = extent[2]) at the ceiling; wall_mounted: hangs on a
wall with its back (min y) on the wall surface."""
ROOM_KINDS: tuple[str, ...] = ("bedroom", "kitchen", "living", "office", "bathroom", "dining", "corridor")
SIZES: tuple[str, ...] = ("small", "medium", "large")
_SIZE_SCALE = {"small": (0.80, 0.88), "medium": (0.96, 1.04), "large": (1.12, 1.22)}


@dataclass
class Part:
    """One textured piece of an asset (all its primitives share material and colour)."""

    mesh: trimesh.Trimesh
    material: str
    rgb: tuple[float, float, float]
    texture_seed: int
    image: np.ndarray | None = None
    """uint8 (H, W, 3) image texture (an asset pack's), mapped by :attr:`uv`; None: the procedural
    texture of ``material`` tinted by ``rgb``, projected along the faces' normals."""
    uv: np.ndarray | None = None
    """(V, 2) texture coordinates of the mesh's vertices for :attr:`image` (OpenGL: v = 0 at the
    image's bottom row)."""
    surface: str = "pattern"
    """How a procedural texture is made (:data:`generators.materials.SURFACES`): the material's pattern, a
    photograph of the material, or bare paint."""


@dataclass
class Asset:
    """One object instance in its own frame (see module docstring); reuse it for identical copies."""

    category: str
    parts: list[Part]
    attributes: dict[str, str]
    description: str
    placement: str
    surface_heights: list[float]

    @property
    def extent(self) -> np.ndarray:
        """(3,) size of the bounding box of all parts, metres."""
        lo = np.min([p.mesh.bounds[0] for p in self.parts], axis=0)
        hi = np.max([p.mesh.bounds[1] for p in self.parts], axis=0)
        return hi - lo

    def to_trimesh(self) -> trimesh.Trimesh:
        """All parts in one mesh, for collision and occupancy checks."""
        return trimesh.util.concatenate([p.mesh for p in self.parts])


@dataclass(frozen=True)
class CategorySpec:
    """Where and how often a category appears in generated rooms."""

    name: str
    placement: str
    rooms: tuple[str, ...]
    weight: float


@dataclass(frozen=True)
class Recipe:
    """A registered category: its spec, its builder and the attribute choices it samples from."""

    spec: CategorySpec
    build: Callable[[Ctx], None]
    noun: str
    materials: tuple[str, ...]
    colours: tuple[str, ...]
    styles: tuple[str, ...]


RECIPES: dict[str, Recipe] = {}


def category(
    name: str,
    placement: str,
    rooms: Sequence[str],
    weight: float,
    *,
    materials: Sequence[str],
    colours: Sequence[str],
    styles: Sequence[str] = ("standard",),
    noun: str | None = None,
) -> Callable[[Callable[[Ctx], None]], Callable[[Ctx], None]]:
    """Register the decorated builder as category ``name`` (checked at import, a library bug otherwise)."""
    assert placement in PLACEMENTS, placement
    assert set(rooms) <= set(ROOM_KINDS), rooms
    assert set(materials) <= set(MATERIALS), materials
    assert set(colours) <= set(COLOURS), colours
    assert name not in RECIPES, name

    def deco(fn: Callable[[Ctx], None]) -> Callable[[Ctx], None]:
        spec = CategorySpec(name, placement, tuple(rooms), float(weight))
        RECIPES[name] = Recipe(
            spec, fn, noun or name.replace("_", " "), tuple(materials), tuple(colours), tuple(styles)
        )
        return fn

    return deco


@dataclass
class Ctx:
    """Builder state for one instance: chosen attributes, random proportions, accumulated meshes."""

    rng: np.random.Generator
    colour: str
    material: str
    size: str
    style: str
    s: float
    """Overall scale from the size class (small ~0.84, medium ~1, large ~1.17)."""
    main_rgb: tuple[float, float, float]
    features: list[str] = field(default_factory=list)
    surface_heights: list[float] = field(default_factory=list)
    groups: dict[tuple[str, str], list[trimesh.Trimesh]] = field(default_factory=dict)

    def u(self, lo: float, hi: float) -> float:
        """A proportion drawn uniformly in [lo, hi)."""
        return float(self.rng.uniform(lo, hi))

    def pick(self, options: Sequence):
        """One of ``options``, uniformly."""
        return options[int(self.rng.integers(len(options)))]

    def chance(self, p: float) -> bool:
        return bool(self.rng.random() < p)

    def add(self, mesh: trimesh.Trimesh, material: str | None = None, colour: str | None = None) -> None:
        """Add a primitive; ``None`` means the instance's main material / colour."""
        key = (material or self.material, colour or "")
        self.groups.setdefault(key, []).append(mesh)

    def feature(self, phrase: str) -> None:
        """A distinctive part for the description, e.g. 'a silver antenna'."""
        self.features.append(phrase)

    def parts(self) -> list[Part]:
        out = []
        for (mat, col), meshes in self.groups.items():
            rgb = self.main_rgb if col == "" else COLOURS[col]
            mesh = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
            out.append(Part(mesh, mat, tuple(float(c) for c in rgb), int(self.rng.integers(2**31 - 1))))
        return out


def size_scale(size: str, rng: np.random.Generator) -> float:
    lo, hi = _SIZE_SCALE[size]
    return float(rng.uniform(lo, hi))


# ---------------------------------------------------------------- primitives (z arguments are bottoms)


def box(sx: float, sy: float, sz: float, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> trimesh.Trimesh:
    """Axis-aligned box of size (sx, sy, sz) whose bottom face is centred at (x, y, z)."""
    return creation.box(extents=(sx, sy, sz), transform=trimesh.transformations.translation_matrix((x, y, z + sz / 2)))


def cyl(r: float, h: float, x: float = 0.0, y: float = 0.0, z: float = 0.0, sections: int = 16) -> trimesh.Trimesh:
    """Vertical cylinder whose bottom disc is centred at (x, y, z)."""
    return creation.cylinder(
        radius=r, height=h, sections=sections, transform=trimesh.transformations.translation_matrix((x, y, z + h / 2))
    )


def rod(p0: Sequence[float], p1: Sequence[float], r: float, sections: int = 8) -> trimesh.Trimesh:
    """Cylinder between two points (legs, tubes, handles, antennas)."""
    return creation.cylinder(radius=r, segment=np.array([p0, p1], dtype=float), sections=sections)


def ellipsoid(
    rx: float, ry: float, rz: float, x: float = 0.0, y: float = 0.0, z: float = 0.0, count: int = 12
) -> trimesh.Trimesh:
    """Ellipsoid centred at (x, y, z) (z here is the centre, not the bottom)."""
    m = creation.uv_sphere(radius=1.0, count=[count, max(6, count * 2 // 3)])
    m.apply_scale((rx, ry, rz))
    m.apply_translation((x, y, z))
    return m


def revolve(
    profile: Sequence[Sequence[float]], x: float = 0.0, y: float = 0.0, z: float = 0.0, sections: int = 20
) -> trimesh.Trimesh:
    """Solid of revolution about the vertical axis through (x, y) from (radius, height) points.

    The profile should start and end on the axis (radius 0) so the solid is closed.
    """
    m = creation.revolve(np.asarray(profile, dtype=float), sections=sections)
    m.apply_translation((x, y, z))
    return m


def torus(
    major: float, minor: float, center: Sequence[float] = (0, 0, 0), axis: str = "z", sections: int = 16
) -> trimesh.Trimesh:
    """Ring of tube radius ``minor``; ``axis`` is the ring's normal (x, y or z)."""
    m = creation.torus(major_radius=major, minor_radius=minor, major_sections=sections, minor_sections=8)
    if axis != "z":
        m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0) if axis == "x" else (1, 0, 0)))
    m.apply_translation(center)
    return m


def rotated(
    mesh: trimesh.Trimesh, angle: float, axis: Sequence[float], point: Sequence[float] = (0, 0, 0)
) -> trimesh.Trimesh:
    """Copy of ``mesh`` rotated by ``angle`` radians about ``axis`` through ``point``."""
    m = mesh.copy()
    m.apply_transform(trimesh.transformations.rotation_matrix(angle, axis, point))
    return m


def ring_positions(n: int, radius: float, phase: float = 0.0) -> np.ndarray:
    """(n, 2) points evenly spaced on a circle (legs of round tables, star bases)."""
    a = phase + 2 * np.pi * np.arange(n) / n
    return np.c_[radius * np.cos(a), radius * np.sin(a)]


def vessel(
    outer: Sequence[Sequence[float]], wall: float, x: float = 0.0, y: float = 0.0, z: float = 0.0, sections: int = 20
) -> trimesh.Trimesh:
    """Open container (mug, bowl, pot, vase) from its outer (radius, height) profile, bottom to rim.

    The inner surface is the outer one moved ``wall`` inwards and up, so the solid stays closed.
    """
    out = [(float(r), float(h)) for r, h in outer]
    inner = [(max(r - wall, 0.002), max(h, wall)) for r, h in reversed(out)]
    return revolve([(0.0, 0.0), *out, *inner, (0.0, wall)], x, y, z, sections)


def moved(mesh: trimesh.Trimesh, offset: Sequence[float]) -> trimesh.Trimesh:
    """``mesh`` translated in place by ``offset`` (returned for chaining)."""
    mesh.apply_translation(offset)
    return mesh
