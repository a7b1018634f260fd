"""The MuJoCo backend (the default): the scene as an MJCF model rendered offscreen.

The scene becomes an MJCF model whose meshes (binary ``.msh``) and textures (PNG) are in-memory assets; it
renders through EGL, falling back to OSMesa, with exact depth (reversed-z float buffer) and per-geom
segmentation that maps to instance ids. Poses and images are in the project's OpenCV convention; the one
conversion to OpenGL camera axes is in :meth:`MujocoRenderer._set_camera`.

The classic MuJoCo renderer shades with at most 8 lights, so each frame enables only the 8 room lights
nearest to the camera on its floor (rooms farther away are behind walls anyway).

No GL context is created at import time or in the constructor (only on the first render), so a process
pool can fork/spawn workers safely.
"""

from __future__ import annotations

import logging
import os
import struct
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from generators.asset_library.core import Part
from generators.layout import Layout
from generators.render.base import (
    ZNEAR_M,
    Culler,
    LightSelector,
    Renderer,
    TextureMapping,
    fovy_from_K,
    part_surface,
    scene_extent,
)
from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.errors import ConfigError

_MUJOCO_PREIMPORTED = "mujoco" in sys.modules and "MUJOCO_GL" not in os.environ
os.environ.setdefault("MUJOCO_GL", "egl")  # must precede the first `import mujoco` in the process
import mujoco  # noqa: E402

log = logging.getLogger(__name__)

MAX_MATERIALS = 998
"""Most materials MuJoCo's classic renderer accepts per model: ``MjrContext`` fails ("Maximum number of
materials is 1000") once ``nmat >= mjMAXMATERIAL - 1`` (MuJoCo 4.0; the constant is not exposed by the
Python bindings)."""


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
    """(material, surface, colour, texture width) of a part, the colour rounded so float noise never splits a
    texture; parts share a texture only within one appearance, so a folded seed never stretches a
    texture made for a part of another size."""
    return (
        part.material,
        part.surface,
        tuple(round(float(c), 6) for c in part.rgb),
        round(TextureMapping.of(part).metres, 4),
    )


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


def _compiled_model(
    layout: Layout, max_width: int, max_height: int, path: Path | None
) -> tuple[mujoco.MjModel, list[int]]:
    """The layout's MuJoCo model and the instance of each geom: from ``path`` when it holds them (a
    model's binary dump reads back exactly), else compiled from :func:`build_mjcf` (drawing every texture,
    seconds on a large scene) and stored there."""
    if path is not None and path.is_file() and path.with_suffix(".npy").is_file():
        try:
            model = mujoco.MjModel.from_binary_path(str(path))
            geom_instance = np.load(path.with_suffix(".npy"), allow_pickle=False).tolist()
            if len(geom_instance) == model.ngeom:
                return model, geom_instance
        except (OSError, ValueError):  # a damaged file: compile again
            pass
    xml, assets, geom_instance = build_mjcf(layout, max_width, max_height)
    try:
        model = mujoco.MjModel.from_xml_string(xml, assets)
    except ValueError as e:
        raise RuntimeError(f"MuJoCo could not compile the scene: {e}") from None
    if path is not None:
        buf = np.zeros(mujoco.mj_sizeModel(model), np.uint8)
        mujoco.mj_saveModel(model, None, buf)
        io.atomic_write_npy(path.with_suffix(".npy"), np.asarray(geom_instance, np.int64))
        io.atomic_write_bytes(path, buf.tobytes())
    return model, geom_instance


class MujocoRenderer(Renderer):
    """MuJoCo classic OpenGL renderer over EGL (OSMesa fallback)."""

    def __init__(self, layout: Layout, max_width: int = 640, max_height: int = 480, compiled: Path | None = None):
        """``compiled``: where the compiled model is kept (``.mjb``, its geoms' instances beside it) for the
        next renderer of the same layout and size: read from there when it is, else built and stored."""
        self.model, geom_instance = _compiled_model(layout, max_width, max_height, compiled)
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
        self,
        level: float = 1.0,
        tint: Sequence[float] = (1.0, 1.0, 1.0),
        lights_off: Sequence[int] = (),
        headlight: bool = True,
    ) -> None:
        tint_a = np.asarray(tint, dtype=np.float64)
        diffuse, ambient, specular = self._base
        self.model.light_diffuse[:] = diffuse * level * tint_a
        self.model.light_ambient[:] = ambient * level * tint_a
        self.model.light_specular[:] = specular * level
        self.model.vis.headlight.ambient[:] = self._headlight[0] * level * tint_a  # MuJoCo's global ambient
        self.model.vis.headlight.diffuse[:] = self._headlight[1] * level * tint_a * float(headlight)
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
