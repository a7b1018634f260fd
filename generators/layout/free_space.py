"""Where a camera may stand (:func:`free_space`) and the clearances that decide it."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from generators.layout.model import DOOR_W, WALL_T, Door, Room

GRID_RES = 0.1
"""Free-space grid cell size (m)."""
WALL_CLEARANCE = 0.35
"""Camera distance kept from walls (m)."""
OBJECT_CLEARANCE = 0.25
"""Camera distance kept from object footprints (m)."""
CAMERA_TOP = 2.0
"""Objects whose bottom is above floor + this never obstruct a camera (ceiling items)."""


def free_space(
    xs: np.ndarray,
    ys: np.ndarray,
    rooms: list[Room],
    doors: list[Door],
    boxes: np.ndarray,
    blocked: list[tuple[float, float, float, float]],
    z0: float,
) -> np.ndarray:
    """Where a camera may stand on a grid of cell centres (xs, ys): inside a room away from its walls,
    through doorways, and at least OBJECT_CLEARANCE from any obstructing object box or blocked rect.

    Used both while furnishing (to keep rooms walkable and connected) and for camera trajectories.
    """
    free = np.zeros(xs.shape, dtype=bool)
    for room in rooms:
        x0, y0, x1, y1 = room.rect
        m = WALL_CLEARANCE
        free |= (xs >= x0 + m) & (xs <= x1 - m) & (ys >= y0 + m) & (ys <= y1 - m)
    for d in doors:
        half_w, reach = DOOR_W / 2 - 0.15, WALL_T / 2 + WALL_CLEARANCE + 0.15
        hx, hy = (half_w, reach) if d.axis == 0 else (reach, half_w)
        free |= (np.abs(xs - d.centre[0]) <= hx) & (np.abs(ys - d.centre[1]) <= hy)
    occupied = np.zeros(xs.shape, dtype=bool)
    for box in np.asarray(boxes).reshape(-1, 2, 3):
        if box[0, 2] > z0 + CAMERA_TOP or box[1, 2] < z0 + 0.05:  # above every camera, or flat (rugs)
            continue
        occupied |= (xs >= box[0, 0]) & (xs <= box[1, 0]) & (ys >= box[0, 1]) & (ys <= box[1, 1])
    for rect in blocked:
        occupied |= (xs >= rect[0]) & (xs <= rect[2]) & (ys >= rect[1]) & (ys <= rect[3])
    if occupied.any():
        free &= ndimage.distance_transform_edt(~occupied) * GRID_RES > OBJECT_CLEARANCE
    return free
