"""What every renderer shares: the :class:`Renderer` interface and what both backends draw and skip.

A renderer draws a :class:`~generators.layout.Layout` from a ``T_wc`` (OpenCV axes) as RGB, metric depth
and instance ids. Both backends draw the same surfaces (:func:`part_surface`: a procedural part's texture
laid on it by its own :class:`TextureMapping`, an asset-pack part's own image), shade each frame with the
same lights (:class:`LightSelector`) and skip what the camera cannot see (:class:`Culler`). Nothing here
imports a GL library.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from generators.asset_library.core import Part
from generators.layout import Layout
from generators.layout.model import DOOR_H, DOOR_W, WALL_T
from generators.materials import DETAIL_M, make_texture, texture_size

MAX_ACTIVE_LIGHTS = 8
"""Lights a frame shades with (MuJoCo's classic renderer shades with at most 8)."""
TEXTURE_SCALE = (0.8, 1.25)
"""Range of the random scale of a procedural part's texture (its pattern's size in the world)."""
ZNEAR_M = 0.02


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
        self,
        level: float = 1.0,
        tint: Sequence[float] = (1.0, 1.0, 1.0),
        lights_off: Sequence[int] = (),
        headlight: bool = True,
    ) -> None:
        """Scale every light by ``level``, multiply its colour by ``tint``, switch off lights by index
        and, with ``headlight`` False, the light along the camera's axis."""

    @abstractmethod
    def set_instance_pose(self, instance_id: int, T_world: np.ndarray) -> None:
        """Move one instance (object-to-world transform), e.g. for the displaced-objects variant."""

    def close(self) -> None:  # noqa: B027  (optional for backends without resources)
        """Free GL resources."""

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def box_corners(lo, hi) -> np.ndarray:
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
        texture = make_texture(part.material, part.rgb, part.texture_seed, mapping.size, mapping.metres, part.surface)
        return v, n, uv, f, texture
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
            portals.append((index[d.rooms[0]], index[d.rooms[1]], box_corners(lo, hi)))
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
                        box_corners((rect[0], rect[1], z - 0.5), (rect[2], rect[3], z + 0.1)),
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
