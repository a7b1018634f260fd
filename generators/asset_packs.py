"""Asset packs: the user's own meshes (GLB / glTF / OBJ / PLY with their textures) as scene objects.

A pack is a directory with a ``manifest.yaml`` (:class:`PackManifest`) that says, per mesh file, its
category, a natural description, where it goes (a placement of
:data:`~generators.asset_library.core.PLACEMENTS`), its real-world size or scale, and its up and
front axes. :func:`load_pack` loads every mesh with trimesh and normalises it into the procedural
library's object frame (metres, z up, front +y, footprint centred, base at z = 0), keeping its UVs and
base-colour texture; the layout then places it like a procedural asset, colliding by its bounding box.

:class:`AssetLibrary` is what the layout samples from: the procedural categories (unless a suite turns
them off) and the packs' categories, a pack category replacing a procedural one of the same name. With
no pack it is exactly the procedural library, random draws included, so procedural scenes are
unchanged. :func:`validate_pack` lists a pack's problems one line each (``openreloc-bench assets``).
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import trimesh
from PIL import Image

from generators.asset_library.core import PLACEMENTS, ROOM_KINDS, Asset, CategorySpec, Part
from generators.assets import categories_for_room, sample_asset
from generators.materials import MATERIALS
from openreloc_bench import config
from openreloc_bench.errors import ConfigError

MANIFEST = "manifest.yaml"
MESH_SUFFIXES = (".glb", ".gltf", ".obj", ".ply")
MAX_TEXTURE_PX = 512
"""Larger textures are downscaled (Lanczos) when loaded: the renderers keep every texture in memory."""
SIZE_RANGE_M = (0.02, 6.0)
"""A normalised asset whose largest side falls outside this range is reported as an absurd size."""
Axis = Literal["+x", "-x", "+y", "-y", "+z", "-z"]


@dataclass
class PackAsset:
    """One mesh of a pack, as the manifest describes it."""

    file: str
    """Mesh file, relative to the pack directory (.glb, .gltf, .obj or .ply)."""
    category: str
    """Category name (objects.json, the describer's vocabulary); entries may share one."""
    description: str
    """Natural-language description written to objects.json, e.g. 'a red ceramic mug with a white handle'."""
    placement: str = "floor"
    """floor, wall (stands against a wall), surface (on tables and shelves), wall_mounted or ceiling."""
    size: float = 0.0
    """Real-world largest side in metres; 0: the file's units times ``scale`` are metres."""
    scale: float = 1.0
    """File units to metres when ``size`` is 0 (0.01 for centimetres)."""
    up: Axis = "+y"
    """The file's up axis (glTF and most OBJ exports: +y)."""
    front: Axis = "+z"
    """The file's front axis, which faces into the room (glTF: +z)."""
    material: str = "plastic"
    """Dominant material (one of the procedural library's), for shading and objects.json."""
    rooms: list[str] = field(default_factory=lambda: [k for k in ROOM_KINDS if k != "corridor"])
    """Room kinds it appears in."""
    weight: float = 1.0
    """Relative frequency against the other categories of its placement (procedural ones are 0.5-3)."""
    surface: bool = False
    """Its top is a surface that smaller surface items may stand on (tables, shelves, counters)."""


@dataclass
class PackManifest:
    """``manifest.yaml`` of an asset pack."""

    name: str = "pack"
    """Pack name (recorded in objects.json attributes)."""
    description: str = ""
    """What the pack holds and where it comes from (licence)."""
    assets: list[PackAsset] = field(default_factory=list)
    """Its meshes."""


_AXES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}


def read_manifest(pack_dir: Path | str) -> tuple[PackManifest, list[str]]:
    """Parse ``pack_dir/manifest.yaml`` (ConfigError when it is missing or malformed) and list the
    problems of its entries, one line each."""
    pack_dir = Path(pack_dir)
    path = pack_dir / MANIFEST
    if not path.is_file():
        raise ConfigError(f"asset pack {pack_dir}: no {MANIFEST}")
    try:
        manifest = config.from_dict(PackManifest, config.load_yaml(path))
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None
    problems = [] if manifest.assets else [f"{path}: 'assets' lists no mesh"]
    for i, a in enumerate(manifest.assets):
        where = f"{path}: assets[{i}] ({a.file})"
        if a.placement not in PLACEMENTS:
            problems.append(f"{where}: unknown placement '{a.placement}' (known: {', '.join(PLACEMENTS)})")
        if a.material not in MATERIALS:
            problems.append(f"{where}: unknown material '{a.material}' (known: {', '.join(MATERIALS)})")
        if unknown := sorted(set(a.rooms) - set(ROOM_KINDS)):
            problems.append(f"{where}: unknown room kind '{unknown[0]}' (known: {', '.join(ROOM_KINDS)})")
        if np.dot(_AXES[a.up], _AXES[a.front]) != 0:
            problems.append(f"{where}: 'up' ({a.up}) and 'front' ({a.front}) must be perpendicular")
        if a.size < 0 or a.scale <= 0 or a.weight <= 0:
            problems.append(f"{where}: 'size' must be >= 0, 'scale' and 'weight' positive")
        if Path(a.file).suffix.lower() not in MESH_SUFFIXES:
            problems.append(f"{where}: not a mesh file (known: {', '.join(MESH_SUFFIXES)})")
        elif Path(a.file).is_absolute() or ".." in Path(a.file).parts:
            problems.append(f"{where}: 'file' must be a path inside the pack")
        elif not (pack_dir / a.file).is_file():
            problems.append(f"{where}: missing file")
    return manifest, problems


def load_manifest(pack_dir: Path | str) -> PackManifest:
    """The checked manifest of a pack; a one-line ConfigError names its first problem."""
    manifest, problems = read_manifest(pack_dir)
    if problems:
        raise ConfigError(problems[0])
    return manifest


def pack_fingerprint(pack_dir: Path | str) -> str:
    """sha256 of the manifest and every file beside it: a scene's spec hash changes with its packs."""
    pack_dir = Path(pack_dir)
    h = hashlib.sha256()
    for path in sorted(p for p in pack_dir.rglob("*") if p.is_file()):
        h.update(path.relative_to(pack_dir).as_posix().encode() + b"\0")
        h.update(hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()[:16]


def _frame(up: str, front: str) -> np.ndarray:
    """Rotation taking the file's axes to the object frame (z up, y front, x = y cross z)."""
    u, f = np.array(_AXES[up], float), np.array(_AXES[front], float)
    return np.stack([np.cross(f, u), f, u])


def _texture(image) -> np.ndarray:
    """RGB uint8 array of a PIL texture, downscaled to at most :data:`MAX_TEXTURE_PX` a side."""
    img = image.convert("RGB")
    if max(img.size) > MAX_TEXTURE_PX:
        k = MAX_TEXTURE_PX / max(img.size)
        img = img.resize((max(1, round(img.width * k)), max(1, round(img.height * k))), Image.Resampling.LANCZOS)
    return np.asarray(img, dtype=np.uint8).copy()


def _surface(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray, bool]:
    """Texture image, UVs and whether the mesh had an image texture (its base colour texture; diffuse
    factors beside it are ignored); an untextured mesh gets a 4 x 4 image of its colour (material
    diffuse, or its mean vertex / face colour) and constant UVs."""
    visual = mesh.visual
    uv = getattr(visual, "uv", None)
    if visual.kind == "texture":
        material = visual.material.to_simple() if hasattr(visual.material, "to_simple") else visual.material
        image = getattr(material, "image", None)
        if image is not None and uv is not None and len(uv) == len(mesh.vertices):
            # the image as it is: exporters write arbitrary diffuse factors beside a texture (OBJ Kd 0.4)
            return _texture(image), np.asarray(uv, dtype=np.float64), True
        rgb = np.asarray(getattr(material, "diffuse", (178, 178, 178, 255)), float)[:3] / 255.0
    else:
        colours = np.asarray(visual.face_colors if visual.kind == "face" else visual.vertex_colors, float)
        rgb = colours[:, :3].mean(axis=0) / 255.0 if len(colours) else np.full(3, 0.7)
    tex = np.broadcast_to(np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8), (4, 4, 3)).copy()
    return tex, np.full((len(mesh.vertices), 2), 0.5), False


def load_mesh_parts(path: Path, entry: PackAsset) -> tuple[list[Part], list[str]]:
    """The normalised parts of one mesh file and its problems (no texture, absurd size).

    Every geometry of the file becomes one part, its scene-graph transform applied; the whole is
    rotated to z up / front +y, scaled to metres and moved so its footprint is centred with the base at
    z = 0."""
    try:
        loaded = trimesh.load(path, force="scene", process=False)
        meshes = [m for m in loaded.dump() if isinstance(m, trimesh.Trimesh) and len(m.faces)]
    except Exception as e:  # trimesh raises many kinds on a broken file
        raise ConfigError(f"{path}: cannot load the mesh ({type(e).__name__}: {e})") from None
    if not meshes:
        raise ConfigError(f"{path}: no triangle mesh in the file")
    R = _frame(entry.up, entry.front)
    problems: list[str] = []
    surfaces = [_surface(m) for m in meshes]
    if not any(textured for _, _, textured in surfaces):
        problems.append(f"{entry.file}: no texture (rendered in one flat colour)")
    verts = [np.asarray(m.vertices, dtype=np.float64) @ R.T * entry.scale for m in meshes]
    lo, hi = np.min([v.min(0) for v in verts], axis=0), np.max([v.max(0) for v in verts], axis=0)
    k = entry.size / float((hi - lo).max()) if entry.size > 0 else 1.0
    shift = -np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]) * k
    largest = float((hi - lo).max()) * k
    if not SIZE_RANGE_M[0] <= largest <= SIZE_RANGE_M[1]:
        problems.append(
            f"{entry.file}: absurd size, largest side {largest:.3g} m after scaling "
            f"(expected {SIZE_RANGE_M[0]}-{SIZE_RANGE_M[1]} m; set 'size' or 'scale')"
        )
    parts = []
    for m, v, (tex, uv, _) in zip(meshes, verts, surfaces):
        mesh = trimesh.Trimesh(v * k + shift, np.asarray(m.faces), process=False)
        rgb = tuple(float(c) for c in tex.reshape(-1, 3).mean(axis=0) / 255.0)
        parts.append(Part(mesh, entry.material, rgb, 0, image=tex, uv=uv))
    return parts, problems


@dataclass
class AssetPack:
    """A loaded pack: its manifest and one normalised :class:`Asset` per entry (identical copies share it)."""

    path: Path
    manifest: PackManifest
    assets: list[Asset]
    problems: list[str]

    @property
    def categories(self) -> dict[str, CategorySpec]:
        """Category -> spec (placement, rooms and weight of its first entry)."""
        out: dict[str, CategorySpec] = {}
        for a in self.manifest.assets:
            out.setdefault(a.category, CategorySpec(a.category, a.placement, tuple(a.rooms), a.weight))
        return out


def load_pack(pack_dir: Path | str) -> AssetPack:
    """Load and normalise every mesh of the pack (ConfigError on a manifest problem or unreadable file)."""
    pack_dir = Path(pack_dir)
    manifest = load_manifest(pack_dir)
    assets, problems = [], []
    for entry in manifest.assets:
        parts, issues = load_mesh_parts(pack_dir / entry.file, entry)
        problems += issues
        top = max(float(p.mesh.bounds[1][2]) for p in parts)
        assets.append(
            Asset(
                category=entry.category,
                parts=parts,
                attributes={"material": entry.material, "pack": manifest.name, "source": entry.file},
                description=entry.description,
                placement=entry.placement,
                surface_heights=[top] if entry.surface else [],
            )
        )
    placements: dict[str, str] = {}
    for entry in manifest.assets:
        if placements.setdefault(entry.category, entry.placement) != entry.placement:
            problems.append(f"{entry.file}: category '{entry.category}' has two placements")
    return AssetPack(pack_dir, manifest, assets, problems)


def validate_pack(pack_dir: Path | str) -> tuple[AssetPack | None, list[str]]:
    """The loaded pack (None when it cannot load) and its problems, one line each: a missing or
    unreadable file, a mesh without texture, an absurd size, an unknown placement..."""
    try:
        _, problems = read_manifest(pack_dir)
        if problems:
            return None, problems
        pack = load_pack(pack_dir)
    except ConfigError as e:
        return None, [str(e)]
    return pack, pack.problems


class AssetLibrary:
    """The categories a scene's layout draws from: procedural ones and those of its asset packs."""

    def __init__(self, packs: list[AssetPack] = (), procedural: bool = True):
        self.procedural = procedural
        self.pack_assets: dict[str, list[Asset]] = {}
        self.pack_specs: dict[str, CategorySpec] = {}
        for pack in packs:
            for cat, spec in pack.categories.items():
                self.pack_specs.setdefault(cat, spec)
            for asset in pack.assets:
                self.pack_assets.setdefault(asset.category, []).append(asset)

    def categories(self, room_kind: str, placement: str) -> list[CategorySpec]:
        """Categories for ``room_kind`` and ``placement``, sorted by name (a pack's replaces a procedural
        one of the same name)."""
        procedural = categories_for_room(room_kind, placement) if self.procedural else []
        if not self.pack_specs:
            return procedural
        by_name = {c.name: c for c in procedural}
        by_name.update({n: s for n, s in self.pack_specs.items() if room_kind in s.rooms and s.placement == placement})
        return [by_name[n] for n in sorted(by_name)]

    def sample(self, category: str, rng: np.random.Generator, like: Asset | None = None) -> Asset:
        """A new instance of ``category``; ``like``: a near-duplicate of that one (same colour, material
        and size). A pack category's instances are its meshes, drawn uniformly (a near-duplicate of
        one is itself)."""
        if category in self.pack_assets:
            if like is not None:
                return like
            choices = self.pack_assets[category]
            return choices[int(rng.integers(len(choices)))]
        if like is None:
            return sample_asset(category, rng)
        a = like.attributes
        return sample_asset(category, rng, colour=a["colour"], material=a["material"], size=a["size"])


@functools.lru_cache(maxsize=16)
def _cached_pack(path: str, fingerprint: str) -> AssetPack:
    return load_pack(path)


def library_for(spec) -> AssetLibrary:
    """The library of a :class:`~generators.spec.SceneSpec`: its packs (loaded once per process and
    content) and, unless ``assets.procedural`` is false, the procedural categories."""
    packs = [_cached_pack(str(p), pack_fingerprint(p)) for p in spec.assets.packs]
    return AssetLibrary(packs, spec.assets.procedural)
