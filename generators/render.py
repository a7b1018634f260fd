"""Offscreen rendering of a :class:`~generators.layout.Layout`: RGB, metric depth and instance ids.

The interface is :class:`Renderer` (``render(T_wc, K, width, height)``, ``set_lighting``,
``set_instance_pose``); :func:`create_renderer` picks a backend. MuJoCo is the default: the scene
becomes an MJCF model whose meshes (binary ``.msh``) and textures (PNG) are in-memory assets; it renders
through EGL, falling back to OSMesa, with exact depth (reversed-z float buffer) and per-geom
segmentation that maps to instance ids. Poses and images are in the project's OpenCV convention;
the one conversion to OpenGL camera axes is in :meth:`MujocoRenderer._set_camera`.

The classic MuJoCo renderer shades with at most 8 lights, so each frame enables only the 8 room
lights nearest to the camera on its floor (rooms farther away are behind walls anyway).

No GL context is created at import time or in the constructor (only on the first render), so a
process pool can fork/spawn workers safely.
"""

from __future__ import annotations

import logging
import os
import struct
import sys
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

import numpy as np

from generators.asset_library.core import Part
from generators.layout import Layout
from generators.layout.model import DOOR_H, DOOR_W, WALL_T
from generators.materials import DETAIL_M, make_texture, texture_size
from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.errors import ConfigError

_MUJOCO_PREIMPORTED = "mujoco" in sys.modules and "MUJOCO_GL" not in os.environ
os.environ.setdefault("MUJOCO_GL", "egl")  # must precede the first `import mujoco` in the process
import mujoco  # noqa: E402

log = logging.getLogger(__name__)

MAX_ACTIVE_LIGHTS = 8
TEXTURE_SCALE = (0.8, 1.25)
"""Range of the random scale of a procedural part's texture (its pattern's size in the world)."""
ZNEAR_M = 0.02
MAX_MATERIALS = 998
"""Most materials MuJoCo's classic renderer accepts per model: ``MjrContext`` fails ("Maximum number of
materials is 1000") once ``nmat >= mjMAXMATERIAL - 1`` (MuJoCo 4.0; the constant is not exposed by the
Python bindings)."""


class Renderer(ABC):
    """Renders RGB uint8, depth float32 metres (0 = no surface) and instance ids int32 (0 = none)."""

    @abstractmethod
    def render(
        self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Render from camera-to-world pose ``T_wc`` (OpenCV axes) with intrinsics ``K``."""

    @abstractmethod
    def render_instances(self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int) -> np.ndarray:
        """Instance ids only (cheap visibility checks)."""

    @abstractmethod
    def render_color(
        self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int, depth: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """RGB (and metric depth, 0 where nothing was drawn, if ``depth``) without the instance pass:
        what an agent's camera needs, at a fraction of :meth:`render`'s cost for small frames."""

    @abstractmethod
    def set_lighting(
        self, level: float = 1.0, tint: Sequence[float] = (1.0, 1.0, 1.0), lights_off: Sequence[int] = ()
    ) -> None:
        """Scale every light by ``level``, multiply its colour by ``tint``, switch off lights by index."""

    @abstractmethod
    def set_instance_pose(self, instance_id: int, T_world: np.ndarray) -> None:
        """Move one instance (object-to-world transform), e.g. for the displaced-objects variant."""

    def close(self) -> None:  # noqa: B027  (optional for backends without resources)
        """Free GL resources."""

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _box_corners(lo, hi) -> np.ndarray:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def _outside_frustum(corners: np.ndarray, T_wc: np.ndarray, tx: float, ty: float) -> np.ndarray:
    """(N,) True where all 8 corners of a box (N,8,3) are beyond one frustum plane (tx, ty = tan half-FOV)."""
    p = (corners - T_wc[:3, 3]) @ T_wc[:3, :3]  # camera-frame (OpenCV) corners
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    return (
        (z < ZNEAR_M).all(-1)
        | (x > z * tx).all(-1)
        | (-x > z * tx).all(-1)
        | (y > z * ty).all(-1)
        | (-y > z * ty).all(-1)
    )


def fovy_from_K(K: np.ndarray, width: int, height: int) -> float:
    """Vertical FOV (deg) of a centred square-pixel K; other intrinsics are not renderable by GL here."""
    K = np.asarray(K, dtype=np.float64)
    if (
        abs(K[0, 0] - K[1, 1]) > 1e-6 * K[1, 1]
        or abs(K[0, 2] - (width - 1) / 2) > 1e-6
        or abs(K[1, 2] - (height - 1) / 2) > 1e-6
    ):
        raise ValueError("renderer needs square pixels and a centred principal point ((W-1)/2, (H-1)/2)")
    return float(np.degrees(2 * np.arctan(0.5 * height / K[1, 1])))


@dataclass(frozen=True)
class TextureMapping:
    """How a procedural part's texture lies on it: a random rotation, scale and offset per part (so no
    two surfaces line up), over a texture wide enough that the part never shows it twice."""

    rotation: float
    """In-plane rotation of the pattern (rad)."""
    scale: float
    """Size of the pattern in the world relative to its design size."""
    offset: tuple[float, float]
    """Texture-coordinate offset in [0, 1)."""
    metres: float
    """Width of surface the texture covers at design size (>= :data:`~generators.materials.DETAIL_M`)."""

    @classmethod
    def of(cls, part: Part) -> TextureMapping:
        """The part's mapping, a deterministic function of its texture seed and its size."""
        rng = np.random.default_rng([int(part.texture_seed), 29])
        rotation = float(rng.uniform(0.0, 2 * np.pi))
        scale = float(np.exp(rng.uniform(*np.log(TEXTURE_SCALE))))
        offset = (float(rng.random()), float(rng.random()))
        extent = np.sort(np.asarray(part.mesh.extents, dtype=np.float64))
        widest_face = float(np.hypot(extent[-1], extent[-2]))  # any rotation of any face fits in it
        return cls(rotation, scale, offset, max(DETAIL_M, widest_face / scale))

    @property
    def size(self) -> int:
        """Texture side in pixels."""
        return texture_size(self.metres)

    def uv(self, points: np.ndarray) -> np.ndarray:
        """(N, 2) texture coordinates of (N, 2) in-plane object-frame metres."""
        c, s = np.cos(self.rotation), np.sin(self.rotation)
        rotated = points @ np.array([[c, s], [-s, c]])
        return rotated / (self.scale * self.metres) + self.offset


def triplanar_uv(
    mesh_vertices: np.ndarray, faces: np.ndarray, mapping: TextureMapping
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unshared vertices, flat normals and box-projected texture coordinates.

    Each face gets its own three vertices so its normal is flat and its texture is projected along its
    dominant normal axis; coordinates follow object-frame metres through ``mapping``, so a moved object
    keeps its texture.
    """
    tri = mesh_vertices[faces]  # (F,3,3)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    dom = np.abs(n).argmax(axis=1)
    axes = np.array([[1, 2], [0, 2], [0, 1]])[dom]  # (F,2) the two in-plane coordinates
    plane = np.take_along_axis(tri, axes[:, None, :].repeat(3, axis=1), axis=2)
    verts = tri.reshape(-1, 3)
    normals = np.repeat(n, 3, axis=0)
    new_faces = np.arange(len(verts), dtype=np.int32).reshape(-1, 3)
    return verts, normals, mapping.uv(plane.reshape(-1, 2)), new_faces


def part_surface(part: Part) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What a renderer draws of a part: vertices, normals, texture coordinates, faces and the RGB
    texture image. Coordinates follow MuJoCo's convention (v = 0 at the image's top row).

    A procedural part gets flat faces, box-projected coordinates (:func:`triplanar_uv`) and its
    material's tileable texture, as wide as :class:`TextureMapping` says; an image-textured part (asset
    packs) keeps its shared vertices, its smooth vertex normals and its own coordinates and image."""
    if part.image is None:
        mapping = TextureMapping.of(part)
        v, n, uv, f = triplanar_uv(np.asarray(part.mesh.vertices), np.asarray(part.mesh.faces), mapping)
        return v, n, uv, f, make_texture(part.material, part.rgb, part.texture_seed, mapping.size, mapping.metres)
    mesh = part.mesh
    return (
        np.asarray(mesh.vertices, dtype=np.float64),
        np.asarray(mesh.vertex_normals, dtype=np.float64),
        np.asarray(part.uv, dtype=np.float64) * [1.0, -1.0] + [0.0, 1.0],
        np.asarray(mesh.faces, dtype=np.int32),
        part.image,
    )


def scene_extent(layout: Layout) -> float:
    """Diagonal of the scene's bounding box plus 1 m: the scale of the depth range."""
    lo = np.min([i.aabb[0] for i in layout.instances], axis=0)
    hi = np.max([i.aabb[1] for i in layout.instances], axis=0)
    return float(np.linalg.norm(hi - lo)) + 1.0


def msh_bytes(vertices: np.ndarray, normals: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> bytes:
    """MuJoCo's binary mesh format: 4 int32 counts, float32 vertices/normals/texcoords, int32 faces."""
    header = struct.pack("<4i", len(vertices), len(normals), len(uv), len(faces))
    return header + b"".join(
        np.ascontiguousarray(a, dtype=dt).tobytes()
        for a, dt in ((vertices, "<f4"), (normals, "<f4"), (uv, "<f4"), (faces, "<i4"))
    )


def _texture_keys(parts: list[Part]) -> Callable[[Part], tuple]:
    """Key under which a part's texture (and material) is shared: (material, colour, seed), so every part
    gets its own noise pattern. A scene with more distinct keys than :data:`MAX_MATERIALS` (a large
    multi-floor house) folds the seeds of each (material, colour) into the most variants that fit;
    scenes within the limit render exactly as before."""
    seeds: dict[tuple, set[int]] = {}
    images = {id(p.image) for p in parts if p.image is not None}  # an image part is its own material
    for p in parts:
        if p.image is None:
            seeds.setdefault(_appearance(p), set()).add(int(p.texture_seed))
    budget = MAX_MATERIALS - len(images)

    def key(p: Part, variants: int | None) -> tuple:
        if p.image is not None:
            return ("image", id(p.image))
        return (*_appearance(p), int(p.texture_seed) if variants is None else int(p.texture_seed) % variants)

    if sum(map(len, seeds.values())) <= budget:
        return lambda p: key(p, None)
    # the count is not monotone in the number of variants (seed % v), so try them from the largest down
    for variants in range(max(map(len, seeds.values())), 0, -1):
        if sum(len({s % variants for s in group}) for group in seeds.values()) <= budget:
            return lambda p, v=variants: key(p, v)
    raise ConfigError(f"the scene has more than {MAX_MATERIALS} distinct (material, colour) pairs, MuJoCo's limit")


def _appearance(part: Part) -> tuple:
    """(material, colour, texture width) of a part, the colour rounded so float noise never splits a
    texture; parts share a texture only within one appearance, so a folded seed never stretches a
    texture made for a part of another size."""
    return (part.material, tuple(round(float(c), 6) for c in part.rgb), round(TextureMapping.of(part).metres, 4))


def build_mjcf(layout: Layout, max_width: int, max_height: int) -> tuple[str, dict[str, bytes], list[int]]:
    """MJCF text, in-memory assets and the instance id of every geom (in geom order)."""
    assets: dict[str, bytes] = {}
    tex_names: dict[tuple, str] = {}
    mesh_cache: dict[int, str] = {}
    asset_xml: list[str] = []
    geom_xml: list[str] = []
    geom_instance: list[int] = []
    lo = np.min([i.aabb[0] for i in layout.instances], axis=0)
    hi = np.max([i.aabb[1] for i in layout.instances], axis=0)
    extent = scene_extent(layout)
    texture_key = _texture_keys([p for inst in layout.instances for p in inst.parts])
    for inst in layout.instances:
        T = inst.transform
        quat = geometry.rotmat_to_quat(T[:3, :3])
        pos = T[:3, 3]
        for part in inst.parts:
            key = texture_key(part)
            mid = (id(part.mesh), id(part.uv))  # identical copies share Part meshes: one mesh asset each
            if key not in tex_names or mid not in mesh_cache:
                v, n, uv, f, image = part_surface(part)
            if key not in tex_names:
                name = f"t{len(tex_names)}"
                tex_names[key] = name
                assets[f"{name}.png"] = io.encode_png(image)
                spec = 0.5 if part.material in ("metal", "glass", "ceramic") else 0.15
                asset_xml.append(f'<texture name="{name}" type="2d" file="{name}.png"/>')
                asset_xml.append(f'<material name="m{name}" texture="{name}" specular="{spec}" shininess="0.3"/>')
            if mid not in mesh_cache:
                mname = f"g{len(mesh_cache)}"
                mesh_cache[mid] = mname
                assets[f"{mname}.msh"] = msh_bytes(v, n, uv, f)
                asset_xml.append(f'<mesh name="{mname}" file="{mname}.msh" inertia="shell"/>')
            geom_xml.append(
                f'<geom type="mesh" mesh="{mesh_cache[mid]}" material="m{tex_names[key]}" '
                f'pos="{pos[0]:.9g} {pos[1]:.9g} {pos[2]:.9g}" quat="{quat[0]:.12g} {quat[1]:.12g} {quat[2]:.12g} {quat[3]:.12g}" '
                f'contype="0" conaffinity="0" group="0" name={quoteattr(f"i{inst.id}_{len(geom_instance)}")}/>'
            )
            geom_instance.append(inst.id)
    light_xml = [
        f'<light name="l{k}" type="point" pos="{li.pos[0]:.6g} {li.pos[1]:.6g} {li.pos[2]:.6g}" diffuse="0.85 0.85 0.85" '
        f'specular="0.1 0.1 0.1" ambient="0.12 0.12 0.12" attenuation="1 0 0.01" castshadow="false"/>'
        for k, li in enumerate(layout.lights)
    ]
    xml = f"""<mujoco model="scene">
  <compiler inertiafromgeom="false"/>
  <statistic extent="{extent:.6g}" center="{(lo[0] + hi[0]) / 2:.6g} {(lo[1] + hi[1]) / 2:.6g} {(lo[2] + hi[2]) / 2:.6g}"/>
  <visual>
    <global offwidth="{max_width}" offheight="{max_height}"/>
    <map znear="{ZNEAR_M / extent:.9g}" zfar="2.0"/>
    <quality shadowsize="0" offsamples="0"/>
    <headlight ambient="0.35 0.35 0.35" diffuse="0.3 0.3 0.3" specular="0 0 0"/>
  </visual>
  <asset>
    {chr(10).join("    " + a for a in asset_xml).strip()}
  </asset>
  <worldbody>
    <camera name="cam" pos="0 0 0"/>
    {chr(10).join("    " + g for g in light_xml + geom_xml).strip()}
  </worldbody>
</mujoco>
"""
    return xml, assets, geom_instance


def camera_floor(floor_z: np.ndarray, z: float) -> int:
    """Index of the storey a camera at height ``z`` is on."""
    return int(np.clip(np.searchsorted(floor_z, z + 1e-6) - 1, 0, len(floor_z) - 1))


class LightSelector:
    """The lights a frame shades with: the :data:`MAX_ACTIVE_LIGHTS` nearest the camera on its storey,
    less those switched off (MuJoCo's classic renderer shades with at most 8; farther rooms are behind
    walls anyway)."""

    def __init__(self, layout: Layout):
        self.pos = np.array([li.pos for li in layout.lights]).reshape(-1, 3)
        self.floor = np.array([li.floor for li in layout.lights], dtype=int)
        self.floor_z = np.asarray(layout.floor_z)

    def active(self, cam: np.ndarray, off: set[int]) -> np.ndarray:
        """(L,) True for the lights on in a frame taken from camera centre ``cam``."""
        d = np.linalg.norm(self.pos - cam, axis=1) + 1000.0 * (self.floor != camera_floor(self.floor_z, cam[2]))
        d[list(off)] = np.inf
        order = np.argsort(d, kind="stable")[:MAX_ACTIVE_LIGHTS]
        active = np.zeros(len(d), dtype=bool)
        active[order[np.isfinite(d[order])]] = True
        return active


class Culler:
    """Which drawables (geoms, nodes) cannot be seen from a camera: those outside the view frustum, and
    those in rooms no line of sight reaches through doorways and stair openings (conservative: the image
    is unchanged). Renderers without culling of their own pay per drawn object, so in a multi-room scene
    this is most of the frame time."""

    def __init__(self, layout: Layout, instance_ids: Sequence[int]):
        """``instance_ids``: the instance of every drawable, in the order of the corners given to :meth:`hidden`."""
        geom_instance = list(instance_ids)
        names = [r.name for r in layout.rooms]
        index = {n: k for k, n in enumerate(names)}
        by_id = layout.by_id()
        self._drawable_rooms = np.zeros((len(geom_instance), len(names)), dtype=bool)
        for g, iid in enumerate(geom_instance):
            inst = by_id[iid]
            rooms = {inst.room, *inst.attributes.get("rooms", "").split(",")} - {"", None}
            self._drawable_rooms[g, [index[n] for n in rooms]] = True
            if not rooms:
                self._drawable_rooms[g] = True
        portals: list[tuple[int, int, np.ndarray]] = []
        for d in layout.doors:
            hx, hy = (DOOR_W / 2, WALL_T) if d.axis == 0 else (WALL_T, DOOR_W / 2)
            lo, hi = d.centre + [-hx, -hy, 0.0], d.centre + [hx, hy, DOOR_H]
            portals.append((index[d.rooms[0]], index[d.rooms[1]], _box_corners(lo, hi)))
        for f, rect in layout.blocked:  # a stair rect on floor f is an opening in floor f + 1
            centre = np.array([(rect[0] + rect[2]) / 2, (rect[1] + rect[3]) / 2])
            below = [r for r in layout.rooms_on(f) if r.contains_xy(centre)]
            above = [r for r in layout.rooms_on(f + 1) if r.contains_xy(centre)]
            if (f + 1, rect) in layout.blocked and below and above:
                z = layout.floor_z[f + 1]
                portals.append(
                    (
                        index[below[0].name],
                        index[above[0].name],
                        _box_corners((rect[0], rect[1], z - 0.5), (rect[2], rect[3], z + 0.1)),
                    )
                )
        self._portals = portals
        self._rooms = layout.rooms
        self._floor_z = np.asarray(layout.floor_z)

    def _visible_rooms(self, T_wc: np.ndarray, tx: float, ty: float) -> np.ndarray | None:
        """Rooms a line of sight can reach: the camera's room(s), then every room behind a chain of
        portals that are each inside the view frustum (conservative). None = camera outside all rooms."""
        cam = T_wc[:3, 3]
        floor = camera_floor(self._floor_z, cam[2])
        seen = {k for k, r in enumerate(self._rooms) if r.floor == floor and r.contains_xy(cam[:2], margin=-0.3)}
        if not seen:
            return None
        if self._portals:
            in_view = ~_outside_frustum(np.stack([c for _, _, c in self._portals]), T_wc, tx, ty)
            grew = True
            while grew:
                grew = False
                for (a, b, _), ok in zip(self._portals, in_view):
                    if ok and (a in seen) != (b in seen):
                        seen |= {a, b}
                        grew = True
        mask = np.zeros(len(self._rooms), dtype=bool)
        mask[list(seen)] = True
        return mask

    def hidden(self, corners: np.ndarray, T_wc: np.ndarray, K: np.ndarray, width: int, height: int) -> np.ndarray:
        """(G,) True for the drawables whose world box corners (G,8,3) cannot be seen."""
        tx = 1.02 * (width / 2) / K[0, 0]
        ty = 1.02 * (height / 2) / K[1, 1]
        out = _outside_frustum(corners, T_wc, tx, ty)
        rooms = self._visible_rooms(T_wc, tx, ty)
        if rooms is not None:
            out |= ~self._drawable_rooms[:, rooms].any(axis=1)
        return out


class MujocoRenderer(Renderer):
    """MuJoCo classic OpenGL renderer over EGL (OSMesa fallback)."""

    def __init__(self, layout: Layout, max_width: int = 640, max_height: int = 480):
        xml, assets, geom_instance = build_mjcf(layout, max_width, max_height)
        try:
            self.model = mujoco.MjModel.from_xml_string(xml, assets)
        except ValueError as e:
            raise RuntimeError(f"MuJoCo could not compile the scene: {e}") from None
        self.data = mujoco.MjData(self.model)
        mujoco.mj_forward(self.model, self.data)
        self.layout = layout
        self.geom_instance = np.array([0] + geom_instance, dtype=np.int32)  # index = geom id + 1 (-1 -> 0)
        self._geom_ids: dict[int, np.ndarray] = {}
        for g, iid in enumerate(geom_instance):
            self._geom_ids.setdefault(iid, []).append(g)  # type: ignore[attr-defined]
        self._geom_ids = {k: np.array(v) for k, v in self._geom_ids.items()}
        self._geom_pose0 = {
            g: (self.model.geom_pos[g].copy(), self.model.geom_quat[g].copy()) for g in range(self.model.ngeom)
        }
        self._update_geom_corners()
        self._culler = Culler(layout, geom_instance)
        self._inst_T0 = {i.id: i.transform.copy() for i in layout.instances}
        self._lights = LightSelector(layout)
        self._base = (
            self.model.light_diffuse.copy(),
            self.model.light_ambient.copy(),
            self.model.light_specular.copy(),
        )
        self._headlight = (np.array(self.model.vis.headlight.ambient), np.array(self.model.vis.headlight.diffuse))
        self._off: set[int] = set()
        self._max_size = (max_width, max_height)
        self._gl = None
        self._mjr: mujoco.MjrContext | None = None
        self._scene = mujoco.MjvScene(self.model, maxgeom=self.model.ngeom + 16)
        self._option = mujoco.MjvOption()
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._camera.fixedcamid = 0

    # ---------------------------------------------------------------------------------------------

    def _context(self) -> mujoco.MjrContext:
        """Create the GL context on first use (EGL, or OSMesa when EGL fails) and make it current."""
        if self._mjr is None:
            if _MUJOCO_PREIMPORTED:
                raise RuntimeError(
                    "mujoco was imported before generators.render without MUJOCO_GL set; "
                    "import generators.render first or set MUJOCO_GL=egl (or osmesa)"
                )
            from mujoco.rendering.classic import gl_context

            try:
                self._gl = gl_context.GLContext(*self._max_size)
                self._gl.make_current()
            except Exception as e:  # EGL missing or broken: fall back to OSMesa
                if os.environ.get("MUJOCO_GL") != "egl":
                    raise
                log.warning("EGL rendering failed (%s); falling back to OSMesa", e)
                from mujoco.osmesa import GLContext

                gl_context.GLContext = GLContext
                os.environ["MUJOCO_GL"] = "osmesa"
                self._gl = GLContext(*self._max_size)
                self._gl.make_current()
            self._mjr = mujoco.MjrContext(self.model, mujoco.mjtFontScale.mjFONTSCALE_100)
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._mjr)
            self._mjr.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        else:
            self._gl.make_current()
        return self._mjr

    def _update_geom_corners(self) -> None:
        """World corners (G,8,3) of every geom's box, for frustum culling."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
        c, h = self.model.geom_aabb[:, :3], self.model.geom_aabb[:, 3:]
        local = c[:, None, :] + signs[None] * h[:, None, :]
        R = self.data.geom_xmat.reshape(-1, 3, 3)
        self._corners = np.einsum("gij,gkj->gki", R, local) + self.data.geom_xpos[:, None, :]

    def _cull(self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int) -> None:
        """Hide (alpha 0: MuJoCo skips them) the geoms the :class:`Culler` finds out of sight."""
        self.model.geom_rgba[:, 3] = np.where(self._culler.hidden(self._corners, T_wc, K, width, height), 0.0, 1.0)

    def _set_camera(self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int) -> None:
        T_gl = geometry.check_pose(T_wc, "camera pose") @ geometry.GL_TO_CV  # the single CV -> GL conversion
        self.data.cam_xpos[0] = T_gl[:3, 3]
        self.data.cam_xmat[0] = T_gl[:3, :3].reshape(-1)
        self.model.cam_fovy[0] = fovy_from_K(K, width, height)
        self._select_lights(T_wc[:3, 3])
        self._cull(T_wc, K, width, height)

    def _select_lights(self, cam: np.ndarray) -> None:
        if len(self._lights.pos):
            self.model.light_active[:] = self._lights.active(cam, self._off).astype(np.uint8)

    def _draw(self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int) -> mujoco.MjrRect:
        if width > self._max_size[0] or height > self._max_size[1]:
            raise ValueError(
                f"image {width}x{height} exceeds the renderer's maximum {self._max_size[0]}x{self._max_size[1]}"
            )
        self._set_camera(T_wc, K, width, height)
        ctx = self._context()
        mujoco.mjv_updateScene(
            self.model, self.data, self._option, None, self._camera, mujoco.mjtCatBit.mjCAT_ALL, self._scene
        )
        rect = mujoco.MjrRect(0, 0, width, height)
        mujoco.mjr_render(rect, self._scene, ctx)
        return rect

    def render(
        self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rect = self._draw(T_wc, K, width, height)
        rgb = np.empty((height, width, 3), dtype=np.uint8)
        zbuf = np.empty((height, width), dtype=np.float32)
        mujoco.mjr_readPixels(rgb, zbuf, rect, self._mjr)  # colour and depth of the same pass
        inst = self._segment(rect)
        depth = self._metric_depth(zbuf[::-1])
        depth[inst == 0] = 0.0
        return np.ascontiguousarray(rgb[::-1]), depth, inst

    def render_instances(self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int) -> np.ndarray:
        return self._segment(self._draw(T_wc, K, width, height))

    def render_color(
        self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int, depth: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        rect = self._draw(T_wc, K, width, height)
        rgb = np.empty((height, width, 3), dtype=np.uint8)
        zbuf = np.empty((height, width), dtype=np.float32) if depth else None
        mujoco.mjr_readPixels(rgb, zbuf, rect, self._mjr)
        if zbuf is None:
            return np.ascontiguousarray(rgb[::-1]), None
        zbuf = zbuf[::-1]
        metric = self._metric_depth(zbuf)
        metric[zbuf <= 0] = 0.0  # nothing drawn there (reversed z: the far plane is 0)
        return np.ascontiguousarray(rgb[::-1]), metric

    def _metric_depth(self, zbuf: np.ndarray) -> np.ndarray:
        """Reversed-z depth buffer -> metric z-depth (same maths as mujoco.Renderer, in float64)."""
        extent = self.model.stat.extent
        near = np.float32(self.model.vis.map.znear * extent)
        far = np.float32(self.model.vis.map.zfar * extent)
        c = np.float32(-0.5) * (-(far + near) / (far - near)) - np.float32(0.5)
        d = np.float32(-0.5) * (-(np.float32(2) * far * near) / (far - near))
        return (d / (zbuf.astype(np.float64) + c)).astype(np.float32)

    def _segment(self, rect: mujoco.MjrRect) -> np.ndarray:
        """Instance ids from a segmentation pass (each scene geom drawn in a colour encoding its index)."""
        flags = self._scene.flags
        saved = flags.copy()
        flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 1
        flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 1
        try:
            mujoco.mjr_render(rect, self._scene, self._mjr)
            buf = np.empty((rect.height, rect.width, 3), dtype=np.uint8)
            mujoco.mjr_readPixels(buf, None, rect, self._mjr)
        finally:
            np.copyto(flags, saved)
        seg = buf[::-1].astype(np.int32)
        segid = seg[..., 0] + (seg[..., 1] << 8) + (seg[..., 2] << 16)
        lut = np.zeros(self._scene.ngeom + 2, dtype=np.int32)
        geom_type = int(mujoco.mjtObj.mjOBJ_GEOM)
        for g in self._scene.geoms[: self._scene.ngeom]:
            if g.objtype == geom_type and g.segid >= 0:
                lut[g.segid + 1] = self.geom_instance[g.objid + 1]
        return lut[np.clip(segid, 0, len(lut) - 1)]

    def set_lighting(
        self, level: float = 1.0, tint: Sequence[float] = (1.0, 1.0, 1.0), lights_off: Sequence[int] = ()
    ) -> None:
        tint_a = np.asarray(tint, dtype=np.float64)
        diffuse, ambient, specular = self._base
        self.model.light_diffuse[:] = diffuse * level * tint_a
        self.model.light_ambient[:] = ambient * level * tint_a
        self.model.light_specular[:] = specular * level
        self.model.vis.headlight.ambient[:] = self._headlight[0] * level * tint_a
        self.model.vis.headlight.diffuse[:] = self._headlight[1] * level * tint_a
        self._off = {int(i) for i in lights_off}
        if len(self._off) >= len(self._lights.pos) > 0:
            raise ValueError("at least one light must stay on")

    def set_instance_pose(self, instance_id: int, T_world: np.ndarray) -> None:
        delta = np.asarray(T_world, dtype=np.float64) @ geometry.invert(self._inst_T0[instance_id])
        for g in self._geom_ids[instance_id]:
            p0, q0 = self._geom_pose0[g]
            G = geometry.qt_to_pose(q0, p0)
            G = delta @ G
            self.model.geom_pos[g] = G[:3, 3]
            self.model.geom_quat[g] = geometry.rotmat_to_quat(G[:3, :3])
        mujoco.mj_kinematics(self.model, self.data)
        self._update_geom_corners()

    def close(self) -> None:
        if self._gl is not None:
            self._gl.make_current()
            if self._mjr is not None:
                self._mjr.free()
            self._gl.free()
        self._gl, self._mjr = None, None


def create_renderer(layout: Layout, backend: str = "mujoco", max_width: int = 640, max_height: int = 480) -> Renderer:
    """Renderer for ``layout``; ``backend`` is 'mujoco' (default) or 'pyrender' (the optional extra)."""
    if backend == "mujoco":
        return MujocoRenderer(layout, max_width, max_height)
    if backend == "pyrender":
        from generators.render_pyrender import PyrenderRenderer  # optional extra: imported on demand

        return PyrenderRenderer(layout, max_width, max_height)
    raise ConfigError(f"unknown renderer backend '{backend}' (known: mujoco, pyrender)")
