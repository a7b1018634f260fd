"""Which way is up in a map's world frame, established from the mapping frames rather than assumed.

Generated scenes are z up; real recordings come in whatever frame their tracker chose (7-Scenes'
KinectFusion volumes have gravity along +y, TUM's motion-capture frame is roughly z up). Two cues
settle it without labels: hand-held and robot cameras are held roughly level, so the mean of their
image-up axes (-y in OpenCV axes) points roughly up; and indoor scenes are full of horizontal surfaces
(floors, table tops, ceilings), whose normals point exactly up. :func:`estimate_up` takes the first as
a guess -- tens of degrees off when every camera looks down at a desk -- and moves it to the mean of the
cloud's normals within a cone around it, narrowing the cone (:data:`SNAP_DEGREES`) as it converges on
the horizontal surfaces: walls, 90 degrees from up, stay outside the first cone unless the guess is
more than 45 degrees off.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

SNAP_DEGREES = (45.0, 30.0, 15.0, 10.0, 10.0)
"""The cones, in turn, of normals averaged into the next estimate."""
MIN_HORIZONTAL_SHARE = 0.05
"""The snap needs at least this share of the cloud on horizontal surfaces (else the guess stands)."""


def estimate_up(poses: np.ndarray, points: np.ndarray, spacing: float) -> np.ndarray:
    """Unit world vector pointing up: the cameras' mean up axis (``poses``: (F, 4, 4) camera-to-world),
    snapped to the horizontal surfaces of ``points`` (the fused cloud, ``spacing`` its point spacing)."""
    guess = -np.asarray(poses)[:, :3, 1].sum(axis=0)
    norm = np.linalg.norm(guess)
    guess = guess / norm if norm > 1e-9 else np.array([0.0, 0.0, 1.0])
    if len(points) < 10:
        return guess
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, np.float64)))
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=4 * spacing, max_nn=30))
    normals = np.asarray(pcd.normals)
    up = guess
    for degrees in SNAP_DEGREES:
        cos = normals @ up
        horizontal = np.abs(cos) >= np.cos(np.radians(degrees))
        if horizontal.mean() < MIN_HORIZONTAL_SHARE:
            return up
        up = (normals[horizontal] * np.sign(cos[horizontal])[:, None]).sum(axis=0)
        up /= np.linalg.norm(up)
    return up


def levelling(up: np.ndarray) -> np.ndarray:
    """(3, 3) rotation taking ``up`` to +z by the smallest turn (the identity when it already is)."""
    rotation, _ = Rotation.align_vectors([[0.0, 0.0, 1.0]], [np.asarray(up, np.float64)])
    return rotation.as_matrix()
