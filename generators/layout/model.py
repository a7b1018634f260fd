"""What a layout is made of: rooms, doors, lights and placed instances, and the building's dimensions.

An :class:`Instance` is anything drawn with an id of its own, structural (walls, floors, ceilings, door
frames, windows, stairs, railings) or furnished; :class:`Layout` is a whole scene, what
:func:`~generators.layout.build_layout` returns and the renderers, trajectories and variants read.
:class:`LayoutDraft` is a layout while it is built.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field, replace
from functools import cached_property

import networkx as nx
import numpy as np
import trimesh

from generators.assets import Part
from generators.materials import COLOURS, photo_materials
from generators.spec import SceneSpec
from openreloc_bench.data.scene import ObjectInfo

WALL_T = 0.1
"""Wall thickness (m)."""
SLAB_T = 0.1
"""Floor and ceiling slab thickness (m)."""
BARE_WALLS_STREAM = 31
PHOTOS_STREAM = 37
"""Tags of the random streams of bare walls and photographed parts (apart from the layout's stream)."""
STOREY_GAP = 0.3
"""Vertical distance from one floor's ceiling surface to the next floor's floor surface (m)."""
DOOR_W, DOOR_H = 0.9, 2.1


@dataclass
class Room:
    """One room: interior rectangle (inside the walls) on one floor."""

    name: str
    kind: str
    floor: int
    rect: tuple[float, float, float, float]
    """Interior (x0, y0, x1, y1) in world metres."""
    z0: float
    """Floor surface height."""
    height: float

    @property
    def area(self) -> float:
        return (self.rect[2] - self.rect[0]) * (self.rect[3] - self.rect[1])

    @property
    def centre(self) -> np.ndarray:
        return np.array([(self.rect[0] + self.rect[2]) / 2, (self.rect[1] + self.rect[3]) / 2, self.z0])

    def contains_xy(self, p: np.ndarray, margin: float = 0.0) -> bool:
        x0, y0, x1, y1 = self.rect
        return x0 + margin <= p[0] <= x1 - margin and y0 + margin <= p[1] <= y1 - margin


@dataclass
class Light:
    """A point light below a room's ceiling."""

    pos: np.ndarray
    room: str
    floor: int
    colour: tuple[float, float, float] = (1.0, 0.97, 0.92)


@dataclass
class Door:
    """A doorway between two rooms (or an opening), centre at floor level."""

    floor: int
    centre: np.ndarray
    axis: int
    """0: the wall runs along x (door crossed along y); 1: the wall runs along y."""
    rooms: tuple[str, str]


@dataclass
class Instance:
    """One placed instance: parts in the object frame plus the object-to-world transform."""

    id: int
    category: str
    parts: list[Part]
    transform: np.ndarray
    structural: bool
    room: str | None
    floor: int
    description: str = ""
    attributes: dict[str, str] = field(default_factory=dict)
    placement: str = "structural"
    support: int | None = None
    """Id of the instance this one stands on (surface items)."""
    surface_heights: list[float] = field(default_factory=list)
    local_bounds: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))

    def __post_init__(self) -> None:
        self.local_bounds = np.array(
            [
                np.min([p.mesh.bounds[0] for p in self.parts], axis=0),
                np.max([p.mesh.bounds[1] for p in self.parts], axis=0),
            ]
        )

    @cached_property
    def aabb(self) -> np.ndarray:
        """(2,3) world box of the transformed vertices (exact, not of the rotated local box).

        Cached: an instance's transform is fixed once placed (displacements make new transforms)."""
        pts = np.concatenate([p.mesh.vertices for p in self.parts]) @ self.transform[:3, :3].T + self.transform[:3, 3]
        return np.stack([pts.min(axis=0), pts.max(axis=0)])

    def to_object_info(self, transform: np.ndarray | None = None) -> ObjectInfo:
        T = self.transform if transform is None else transform
        pts = np.concatenate([p.mesh.vertices for p in self.parts]) @ T[:3, :3].T + T[:3, 3]
        aabb = np.round(np.stack([pts.min(axis=0), pts.max(axis=0)]), 5)
        attrs = dict(self.attributes)
        attrs["placement"] = self.placement
        return ObjectInfo(
            id=self.id,
            category=self.category,
            description=self.description,
            attributes=attrs,
            room=self.room,
            floor=self.floor,
            structural=self.structural,
            aabb=aabb.tolist(),
            transform=np.round(T, 9).tolist(),
        )


@dataclass
class Layout:
    """A whole scene: rooms, doors, lights and every placed instance."""

    rooms: list[Room]
    doors: list[Door]
    lights: list[Light]
    instances: list[Instance]
    footprint: tuple[float, float]
    """(length along x, depth along y) of the building."""
    floor_z: list[float]
    ceiling_height: float
    blocked: list[tuple[int, tuple[float, float, float, float]]] = field(default_factory=list)
    """(floor, rect) regions a camera must not enter (stairs, floor openings)."""

    def by_id(self) -> dict[int, Instance]:
        return {i.id: i for i in self.instances}

    def rooms_on(self, floor: int) -> list[Room]:
        return [r for r in self.rooms if r.floor == floor]

    def objects(self) -> list[ObjectInfo]:
        return [i.to_object_info() for i in self.instances]

    def room_graph(self) -> nx.Graph:
        """Rooms joined by doors (and stairs between floors)."""
        g = nx.Graph()
        g.add_nodes_from(r.name for r in self.rooms)
        g.add_edges_from(d.rooms for d in self.doors)
        return g


class LayoutDraft:
    """A layout while it is built: the scene's one random stream (every choice draws from it in a fixed
    order, so a spec and seed give one layout) and the rooms, doors, lights and instances so far."""

    def __init__(self, spec: SceneSpec):
        self.spec = spec
        self.rng = np.random.default_rng(spec.seed)
        self.instances: list[Instance] = []
        self.rooms: list[Room] = []
        self.doors: list[Door] = []
        self.lights: list[Light] = []
        self.blocked: list[tuple[int, tuple[float, float, float, float]]] = []
        self.storey = spec.ceiling_height + STOREY_GAP
        """Height from one floor surface to the next."""

    def tex_seed(self) -> int:
        return int(self.rng.integers(1 << 30))

    def bare_walls(self, room: str) -> bool:
        """Whether ``room``'s walls are bare paint (``spec.bare_wall_share`` of the rooms): drawn from the
        seed and the room's name, not from the layout's stream, so the rest of the layout does not move."""
        draw = np.random.default_rng([self.spec.seed, zlib.crc32(room.encode()), BARE_WALLS_STREAM]).random()
        return bool(draw < self.spec.bare_wall_share)

    def finish_surfaces(self) -> None:
        """Give ``spec.photo_share`` of the objects' parts a photograph of their material for a texture
        (where there is one), each part's draw from the seed and its texture seed, so identical copies
        stay identical and the layout's stream does not move."""
        photographed = photo_materials()
        for inst in self.instances:
            if inst.structural:
                continue
            inst.parts = [
                replace(p, surface="photo")
                if p.image is None
                and p.material in photographed
                and np.random.default_rng([self.spec.seed, p.texture_seed, PHOTOS_STREAM]).random()
                < self.spec.photo_share
                else p
                for p in inst.parts
            ]

    def add(self, **kw) -> Instance:
        """A new instance, numbered after the last one."""
        inst = Instance(id=len(self.instances) + 1, **kw)
        self.instances.append(inst)
        return inst

    def rooms_on(self, f: int) -> list[Room]:
        return [r for r in self.rooms if r.floor == f]

    def layout(self, footprint: tuple[float, float]) -> Layout:
        """The finished layout, on a building of ``footprint`` (x length, y depth)."""
        floor_z = [f * self.storey for f in range(self.spec.floors)]
        return Layout(
            self.rooms,
            self.doors,
            self.lights,
            self.instances,
            footprint,
            floor_z,
            self.spec.ceiling_height,
            self.blocked,
        )


def box_mesh(lo: np.ndarray | tuple, hi: np.ndarray | tuple) -> trimesh.Trimesh:
    """Axis-aligned box between two corners."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return trimesh.creation.box(extents=hi - lo, transform=trimesh.transformations.translation_matrix((lo + hi) / 2))


def make_part(meshes: list[trimesh.Trimesh], material: str, colour: str, seed: int, surface: str = "pattern") -> Part:
    """One part of ``meshes`` in a named colour, its texture drawn from ``seed``."""
    return Part(trimesh.util.concatenate(meshes), material, COLOURS[colour], seed, surface=surface)
