"""The pyrender backend: RGB, metric depth and instance ids of a :class:`~generators.layout.Layout`.

Same scene description, same geometry and textures as the MuJoCo backend
(:func:`~generators.render.base.part_surface`), shaded by pyrender's physically based pipeline
(metallic-roughness materials, linear-light shading, sRGB output), with the same light selection and the
same :class:`~generators.render.base.Culler`. Two choices make its depth and ids agree with MuJoCo's: the
main framebuffer is single-sampled (pyrender's 4x MSAA resolves depth to a sample off the pixel centre,
an error of millimetres on grazing surfaces, and blends instance colours on edges), and the camera is
MuJoCo's symmetric perspective (vertical FOV from K). Nodes are drawn and lights summed in a fixed order
(:class:`_OrderedScene`), so a spec gives the same bytes.

It needs the optional ``pyrender`` extra (the ``pyrender2`` distribution, a numpy-2 fix of pyrender
0.1.45 that accepts MuJoCo's PyOpenGL). It renders through EGL in the same process as MuJoCo; closing
it destroys its own context but never terminates the EGL display, which MuJoCo's contexts share.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence

import numpy as np

from generators.layout import Layout
from generators.render.base import (
    ZNEAR_M,
    Culler,
    LightSelector,
    Renderer,
    box_corners,
    fovy_from_K,
    part_surface,
    scene_extent,
)
from openreloc_bench import geometry
from openreloc_bench.errors import ConfigError

logging.getLogger("OpenGL.acceleratesupport").setLevel(logging.WARNING)  # "no OpenGL_accelerate": noise
os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa" if os.environ.get("MUJOCO_GL") == "osmesa" else "egl")
try:
    import pyrender
    from OpenGL import GL
    from pyrender.renderer import Renderer as _PyrenderGL
except ImportError as e:  # the optional extra is missing
    raise ConfigError(
        f"backend 'pyrender' needs the pyrender extra ({e}); install it with pip install -e '.[pyrender]' "
        "or OPENRELOC_EXTRAS=dev,pyrender bash scripts/setup.sh, or use backend 'mujoco'"
    ) from None

LIGHT_INTENSITY = 3.5
"""Point light intensity (candela): with the ambient and head light below, a room lit like MuJoCo's."""
AMBIENT = 0.15
HEADLIGHT = 0.7
"""Directional light along the camera's axis (lux), as MuJoCo's headlight."""
GLOSSY = ("metal", "glass", "ceramic")


class _SingleSampleGL(_PyrenderGL):
    """pyrender's renderer with a single-sample main framebuffer: depth and ids at pixel centres."""

    def _configure_main_framebuffer(self):
        fresh = self._main_fb is None or self._main_fb_dims != (self.viewport_width, self.viewport_height)
        super()._configure_main_framebuffer()
        if fresh:
            for buf, fmt in ((self._main_cb_ms, GL.GL_RGBA), (self._main_db_ms, GL.GL_DEPTH_COMPONENT24)):
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, buf)
                GL.glRenderbufferStorageMultisample(
                    GL.GL_RENDERBUFFER, 0, fmt, self.viewport_width, self.viewport_height
                )


class _Offscreen(pyrender.OffscreenRenderer):
    """Offscreen pyrender with :class:`_SingleSampleGL` that leaves the shared EGL display alive."""

    def _create(self):
        super()._create()
        self._renderer = _SingleSampleGL(self.viewport_width, self.viewport_height)

    def delete(self):
        if self._platform is None:
            return
        self._platform.make_current()
        self._renderer.delete()
        display = getattr(self._platform, "_egl_display", None)
        if display is not None:  # EGL: destroy our context only (eglTerminate would kill MuJoCo's)
            from OpenGL import EGL

            EGL.eglMakeCurrent(display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, EGL.EGL_NO_CONTEXT)
            EGL.eglDestroyContext(display, self._platform._egl_context)
            self._platform._egl_context = self._platform._egl_display = None  # its __del__ would terminate
        else:
            self._platform.delete_context()
        self._renderer = self._platform = None


class _OrderedScene(pyrender.Scene):
    """A pyrender scene whose mesh and light nodes iterate in the order they were added.

    pyrender keeps them in sets, whose order follows memory addresses and so changes between runs:
    which of two coplanar surfaces wins the depth test and the order lights are summed in would too,
    and the same scene would not give the same bytes."""

    def __init__(self, **kw):
        self._order: dict[pyrender.Node, int] = {}
        super().__init__(**kw)

    def add_node(self, node, parent_node=None):
        self._order.setdefault(node, len(self._order))
        super().add_node(node, parent_node)

    @property
    def mesh_nodes(self):
        return sorted(self._mesh_nodes, key=self._order.__getitem__)

    @property
    def light_nodes(self):
        nodes = self._point_light_nodes | self._spot_light_nodes | self._directional_light_nodes
        return sorted(nodes, key=self._order.__getitem__)


def _id_colour(instance_id: int) -> np.ndarray:
    return np.array([instance_id & 255, (instance_id >> 8) & 255, (instance_id >> 16) & 255], dtype=np.uint8)


class PyrenderRenderer(Renderer):
    """pyrender over EGL (or OSMesa with ``MUJOCO_GL=osmesa``), single-sampled, PBR-shaded."""

    def __init__(self, layout: Layout, max_width: int = 640, max_height: int = 480):
        self.layout = layout
        self._max_size = (max_width, max_height)
        self.scene = _OrderedScene(bg_color=(0.0, 0.0, 0.0, 1.0), ambient_light=(AMBIENT,) * 3)
        self._surfaces: dict[tuple, dict] = {}
        self._materials: dict[tuple, pyrender.MetallicRoughnessMaterial] = {}  # one material per texture
        self._nodes: dict[int, list[int]] = {}  # instance id -> indices into the lists below
        self._seg: dict[pyrender.Node, np.ndarray] = {}
        node_list, local_corners, node_instance = [], [], []
        for inst in layout.instances:
            for part in inst.parts:
                # a mesh per node (primitives shared by identical copies), so each node culls on its own
                node = self.scene.add(pyrender.Mesh([self._primitive(part)]), pose=inst.transform)
                self._seg[node] = _id_colour(inst.id)
                self._nodes.setdefault(inst.id, []).append(len(node_list))
                node_list.append(node)
                local_corners.append(box_corners(*part.mesh.bounds))
                node_instance.append(inst.id)
        self._node_list, self._local_corners = node_list, np.array(local_corners)
        self._corners = np.stack([self._world_corners(k) for k in range(len(node_list))])
        self._culler = Culler(layout, node_instance)
        self._lights = []
        for li in layout.lights:
            light = pyrender.PointLight(color=np.ones(3), intensity=LIGHT_INTENSITY)
            T = np.eye(4)
            T[:3, 3] = li.pos
            self.scene.add(light, pose=T)
            self._lights.append(light)
        self._selector = LightSelector(layout)
        self._headlight = pyrender.DirectionalLight(color=np.ones(3), intensity=HEADLIGHT)
        extent = scene_extent(layout)
        self._camera = pyrender.PerspectiveCamera(yfov=1.0, znear=ZNEAR_M, zfar=2.0 * extent)
        self._cam_node = self.scene.add(self._camera, pose=np.eye(4))
        self._head_node = self.scene.add(self._headlight, pose=np.eye(4))
        self._level, self._tint, self._off = 1.0, np.ones(3), set()
        self._gl: _Offscreen | None = None  # created on the first render

    def _world_corners(self, k: int) -> np.ndarray:
        T = self.scene.get_pose(self._node_list[k])
        return self._local_corners[k] @ T[:3, :3].T + T[:3, 3]

    def _primitive(self, part) -> pyrender.Primitive:
        """A new primitive of ``part`` (pyrender binds each to one mesh); identical copies share its
        arrays, material and texture."""
        key = (id(part.mesh), id(part.image), part.material, part.rgb, part.texture_seed)
        if key not in self._surfaces:
            verts, normals, uv, faces, image = part_surface(part)
            tkey = (id(part.image),) if part.image is not None else (part.material, part.rgb, part.texture_seed)
            if tkey not in self._materials:
                sampler = pyrender.Sampler(
                    magFilter=GL.GL_LINEAR, minFilter=GL.GL_LINEAR_MIPMAP_LINEAR, wrapS=GL.GL_REPEAT, wrapT=GL.GL_REPEAT
                )
                self._materials[tkey] = pyrender.MetallicRoughnessMaterial(
                    baseColorTexture=pyrender.Texture(source=image, source_channels="RGB", sampler=sampler),
                    metallicFactor=0.0,
                    roughnessFactor=0.45 if part.material in GLOSSY else 0.85,
                )
            uv = uv * [1.0, -1.0] + [0.0, 1.0]  # pyrender uploads images bottom row first
            self._surfaces[key] = dict(
                positions=verts, normals=normals, texcoord_0=uv, indices=faces, material=self._materials[tkey]
            )
        return pyrender.Primitive(**self._surfaces[key], mode=pyrender.constants.GLTF.TRIANGLES)

    def _context(self, width: int, height: int) -> _Offscreen:
        if width > self._max_size[0] or height > self._max_size[1]:
            raise ValueError(
                f"image {width}x{height} exceeds the renderer's maximum {self._max_size[0]}x{self._max_size[1]}"
            )
        if self._gl is None:
            self._gl = _Offscreen(*self._max_size)
        self._gl.viewport_width, self._gl.viewport_height = width, height
        return self._gl

    def _set_camera(self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int) -> None:
        T_gl = geometry.check_pose(T_wc, "camera pose") @ geometry.GL_TO_CV  # OpenCV -> OpenGL camera axes
        self._camera.yfov = float(np.radians(fovy_from_K(K, width, height)))
        self._camera.aspectRatio = width / height
        self.scene.set_pose(self._cam_node, T_gl)
        self.scene.set_pose(self._head_node, T_gl)
        self._select_lights(T_wc[:3, 3])
        for node, hide in zip(self._node_list, self._culler.hidden(self._corners, T_wc, K, width, height)):
            node.mesh.is_visible = not hide

    def _select_lights(self, cam: np.ndarray) -> None:
        """The MuJoCo backend's lights (:class:`~generators.render.base.LightSelector`), scaled and tinted."""
        for light, on in zip(self._lights, self._selector.active(cam, self._off)):
            light.intensity = LIGHT_INTENSITY * self._level if on else 0.0
            light.color = self._tint

    def render(
        self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rgb, depth = self.render_color(T_wc, K, width, height, depth=True)
        inst = self._segment(width, height)
        depth[inst == 0] = 0.0
        return rgb, depth, inst

    def render_instances(self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int) -> np.ndarray:
        self._set_camera(T_wc, K, width, height)
        return self._segment(width, height)

    def render_color(
        self, T_wc: np.ndarray, K: np.ndarray, width: int, height: int, depth: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        self._set_camera(T_wc, K, width, height)
        gl = self._context(width, height)
        rgb, z = gl.render(self.scene)
        return np.ascontiguousarray(rgb), (np.ascontiguousarray(z, dtype=np.float32) if depth else None)

    def _segment(self, width: int, height: int) -> np.ndarray:
        gl = self._context(width, height)
        seg, _ = gl.render(self.scene, pyrender.RenderFlags.SEG, self._seg)
        seg = seg.astype(np.int32)
        return seg[..., 0] + (seg[..., 1] << 8) + (seg[..., 2] << 16)

    def set_lighting(
        self,
        level: float = 1.0,
        tint: Sequence[float] = (1.0, 1.0, 1.0),
        lights_off: Sequence[int] = (),
        headlight: bool = True,
    ) -> None:
        off = {int(i) for i in lights_off}
        if len(off) >= len(self._lights) > 0:
            raise ValueError("at least one light must stay on")
        self._level, self._tint, self._off = float(level), np.asarray(tint, dtype=np.float64), off
        self.scene.ambient_light = AMBIENT * self._level * self._tint
        self._headlight.intensity = HEADLIGHT * self._level * float(headlight)
        self._headlight.color = self._tint

    def set_instance_pose(self, instance_id: int, T_world: np.ndarray) -> None:
        for k in self._nodes[instance_id]:
            self.scene.set_pose(self._node_list[k], np.asarray(T_world, dtype=np.float64))
            self._corners[k] = self._world_corners(k)

    def close(self) -> None:
        if self._gl is not None:
            self._gl.delete()
        self._gl = None
