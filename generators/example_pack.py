"""A small example asset pack, written with trimesh from numpy-made meshes and textures.

It exercises what a real pack needs: GLB and OBJ (+ MTL + PNG) files, image textures with their own
UVs, files in centimetres (``scale``) and z-up (``up``), and every placement class but ``ceiling``.
Deterministic: the same bytes on every run, so ``scenes/asset-packs/example`` is checked against it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

from generators.materials import make_texture

# faces of a unit box: (normal axis, sign), each drawn as a quad with the full texture on it
_FACES = [(0, 1), (0, -1), (1, 1), (1, -1), (2, 1), (2, -1)]


def textured_box(extents, texture: np.ndarray, repeat: float = 1.0) -> trimesh.Trimesh:
    """Box centred at the origin whose six faces each carry the whole ``texture`` (``repeat`` times),
    upright on the side faces (image top towards +z)."""
    half = np.asarray(extents, float) / 2
    verts, uvs, faces = [], [], []
    for axis, sign in _FACES:
        normal = np.zeros(3)
        normal[axis] = sign
        v_dir = np.eye(3)[2] if axis != 2 else np.eye(3)[1]  # image up: +z on the sides, +y on top/bottom
        u_dir = np.cross(v_dir, normal)  # u x v = outward normal: counter-clockwise seen from outside
        n = len(verts)
        for uu, vv in ((0, 0), (1, 0), (1, 1), (0, 1)):
            verts.append(half * (normal + (2 * uu - 1) * u_dir + (2 * vv - 1) * v_dir))
            uvs.append([uu * repeat, vv * repeat])
        faces += [[n, n + 1, n + 2], [n, n + 2, n + 3]]
    visual = trimesh.visual.TextureVisuals(uv=np.array(uvs, float), image=Image.fromarray(texture))
    return trimesh.Trimesh(np.array(verts), np.array(faces), visual=visual, process=False)


def textured_sphere(radius: float, texture: np.ndarray, count: int = 16) -> trimesh.Trimesh:
    """Latitude-longitude sphere (z up) with equirectangular UVs."""
    lat = np.linspace(0, np.pi, count + 1)
    lon = np.linspace(0, 2 * np.pi, 2 * count + 1)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    verts = radius * np.stack([np.sin(la) * np.cos(lo), np.sin(la) * np.sin(lo), np.cos(la)], -1).reshape(-1, 3)
    uv = np.stack([lo / (2 * np.pi), 1 - la / np.pi], -1).reshape(-1, 2)
    w = 2 * count + 1
    faces = []
    for i in range(count):
        for j in range(2 * count):
            a, b, c, d = i * w + j, i * w + j + 1, (i + 1) * w + j, (i + 1) * w + j + 1
            faces += [[a, c, b], [b, c, d]]
    visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.fromarray(texture))
    return trimesh.Trimesh(verts, np.array(faces), visual=visual, process=False)


def _poster_image(size: int = 128) -> np.ndarray:
    """Top half warm red, bottom half deep blue, a cream border: an orientation check as well as a poster."""
    img = np.zeros((size, size, 3), np.uint8)
    img[: size // 2] = (200, 40, 30)
    img[size // 2 :] = (30, 50, 160)
    yy, xx = np.mgrid[0:size, 0:size]
    img[(np.hypot(yy - size / 2, xx - size / 2) < size / 5)] = (240, 200, 40)
    b = size // 12
    img[:b], img[-b:], img[:, :b], img[:, -b:] = (235, 225, 200), (235, 225, 200), (235, 225, 200), (235, 225, 200)
    return img


def _globe_image(size: int = 128) -> np.ndarray:
    rng = np.random.default_rng(7)
    land = make_texture("stone", (0.5, 0.5, 0.5), 3, size)[..., 0] > 128
    img = np.where(land[..., None], np.array([60, 140, 60], np.uint8), np.array([40, 90, 180], np.uint8))
    return np.clip(img.astype(int) + rng.integers(-12, 12, img.shape), 0, 255).astype(np.uint8)


def _crate_image(size: int = 128) -> np.ndarray:
    img = make_texture("wood", (0.62, 0.45, 0.26), 11, size).copy()
    for k in range(0, size, size // 4):
        img[k : k + 3] = (img[k : k + 3] * 0.45).astype(np.uint8)  # dark plank gaps
    return img


def _y_up(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Rotate a z-up, front +y mesh to y up (glTF); its front becomes -z (the manifest says so)."""
    mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, (1, 0, 0)))
    return mesh


MANIFEST_YAML = """\
# An asset pack: meshes beside this manifest, one entry per mesh file.
name: example
description: example pack written by generators/example_pack.py (numpy-made textures, public domain)
assets:
  - file: crate.glb              # GLB / glTF / OBJ / PLY, relative to this directory
    category: storage_crate      # objects.json category (entries may share one)
    description: a wooden storage crate with dark plank gaps
    placement: wall              # floor | wall | surface | wall_mounted | ceiling
    scale: 0.01                  # file units -> metres (this file is in centimetres)
    up: +y                       # the file's up axis (glTF: +y)
    front: -z                    # the file's front axis, turned to face into the room
    material: wood               # for shading and objects.json
    rooms: [bedroom, kitchen, living, office, dining]
    weight: 2.0                  # frequency against the other categories of its placement
    surface: true                # smaller items may stand on its top
  - file: globe/globe.obj        # OBJ with its MTL and PNG texture
    category: globe
    description: a blue and green globe on a black stand
    placement: surface
    size: 0.32                   # real-world largest side in metres (instead of scale)
    up: +z
    front: +y
    rooms: [living, office, bedroom]
    weight: 2.0
  - file: poster.glb             # two geometries (board and frame) in one glTF scene
    category: poster
    description: a red and blue poster with a yellow disc
    placement: wall_mounted
    front: -z
    material: paper
    weight: 3.0
"""
"""The example pack's manifest (also the README's example of one)."""


def write_example_pack(out: Path | str) -> Path:
    """Write the example pack into ``out`` (created); returns it."""
    out = Path(out)
    (out / "globe").mkdir(parents=True, exist_ok=True)
    # a 60 x 40 x 45 cm crate, in centimetres, y up (glTF)
    crate = _y_up(textured_box((60, 40, 45), _crate_image()))
    (out / "crate.glb").write_bytes(crate.export(file_type="glb"))
    # a globe on a stand, z up, arbitrary units (the manifest gives its real size)
    stand = textured_box((0.5, 0.5, 0.3), np.full((4, 4, 3), 20, np.uint8))
    stand.apply_translation((0, 0, 0.15))
    ball = textured_sphere(0.9, _globe_image())
    ball.apply_translation((0, 0, 1.25))
    globe = trimesh.util.concatenate([stand, ball])  # one mesh, the two textures packed in an atlas
    text, textures = trimesh.exchange.obj.export_obj(
        globe, include_texture=True, return_texture=True, mtl_name="globe.mtl", include_normals=False
    )
    (out / "globe" / "globe.obj").write_text(text)
    for name, data in sorted(textures.items()):
        (out / "globe" / name).write_bytes(data)
    # a poster: a thin board and a frame, two geometries of one glTF scene
    board = textured_box((0.6, 0.02, 0.8), _poster_image())
    board.apply_translation((0, 0.01, 0))
    frame = textured_box((0.66, 0.02, 0.86), np.full((4, 4, 3), (90, 60, 35), np.uint8))
    poster = trimesh.Scene()
    poster.add_geometry(_y_up(board), geom_name="board")
    poster.add_geometry(_y_up(frame), geom_name="frame")
    (out / "poster.glb").write_bytes(poster.export(file_type="glb"))
    (out / "manifest.yaml").write_text(MANIFEST_YAML)
    return out
