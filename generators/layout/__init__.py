"""Indoor layouts: rooms, walls, doors, windows, stairs and furnished objects as placed instances.

:func:`build_layout` makes a scene's :class:`Layout` from its spec in three steps, one module each:
the floor plan of every storey (:mod:`~generators.layout.floor_plan`: rooms, stairs, doorways), the
structure as geometry (:mod:`~generators.layout.structure`: slabs, walls, door frames, windows, stairs,
railings, lights) and the furnishing (:mod:`~generators.layout.furnish`: assets placed from the scene's
asset library). :mod:`~generators.layout.model` holds the layout's types and the building's dimensions,
:mod:`~generators.layout.free_space` where a camera may stand. Multi-floor scenes stack storeys with
the same footprint.
"""

from generators.layout.build import build_layout
from generators.layout.model import Door, Instance, Layout, Light, Room

__all__ = ["Door", "Instance", "Layout", "Light", "Room", "build_layout"]
