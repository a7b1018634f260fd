"""A one-line, human-readable placement of a camera among the objects it matched.

"1.8 m in front of the blue sofa, facing the dining table": the paper's argument for object-level
maps is that a pose expressed relative to named objects is something a person or an agent can act
on, which an anchor-based map cannot say. The anchor is the matched object closest to the camera
(distance to its 3D box); the object faced is the one closest to the optical axis. Objects are
named by the describer's phrase when it names the landmark's known category (it adds colour), else
by the category, else by the phrase alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_ARTICLES = ("a ", "an ", "the ")
UP = np.array([0.0, 0.0, 1.0])
"""The generator's up; a map gives its own (:attr:`.map.ObjectMap.up`)."""


@dataclass
class PlacedObject:
    """A matched landmark as the explanation sees it."""

    center: np.ndarray
    """(3,) world centre."""
    box_min: np.ndarray
    box_max: np.ndarray
    category: str | None = None
    """Ground-truth category when the map knows it."""
    phrase: str | None = None
    """The describer's phrase for the query object matched to it."""

    @property
    def label(self) -> str:
        phrase = _strip_article(self.phrase) if self.phrase else None
        if self.category and phrase and phrase.lower().endswith(self.category.lower()):
            return phrase
        return self.category or phrase or "object"


def _strip_article(text: str) -> str:
    t = text.strip()
    for a in _ARTICLES:
        if t.lower().startswith(a):
            return t[len(a) :]
    return t


def _bearing(T_wc: np.ndarray, point: np.ndarray, up: np.ndarray) -> float:
    """Horizontal angle (degrees) of ``point`` from the camera's viewing direction; + = to the right."""
    forward, right = T_wc[:3, 2] - (T_wc[:3, 2] @ up) * up, T_wc[:3, 0] - (T_wc[:3, 0] @ up) * up
    d = np.asarray(point, dtype=np.float64) - T_wc[:3, 3]
    f = float(d @ forward / max(np.linalg.norm(forward), 1e-9))
    r = float(d @ right / max(np.linalg.norm(right), 1e-9))
    return float(np.degrees(np.arctan2(r, f)))


def explain_pose(T_wc: np.ndarray, objects: list[PlacedObject], up: np.ndarray = UP) -> str:
    """One line placing the camera ``T_wc`` relative to ``objects`` (empty string without objects), in
    a world whose up is ``up`` (unit)."""
    if not objects:
        return ""
    eye = np.asarray(T_wc, dtype=np.float64)[:3, 3]
    dist = [float(np.linalg.norm(eye - np.clip(eye, o.box_min, o.box_max))) for o in objects]
    anchor = int(np.argmin(dist))
    off_axis = [abs(_bearing(T_wc, o.center, up)) for o in objects]
    others = [i for i in range(len(objects)) if i != anchor] or [anchor]
    faced = min(others, key=lambda i: off_axis[i])
    bearing = _bearing(T_wc, objects[anchor].center, up)
    name = objects[anchor].label
    if abs(bearing) <= 45:
        where = f"{dist[anchor]:.1f} m in front of the {name}"
    else:
        side = "right" if bearing > 0 else "left"
        if abs(bearing) > 135:
            side = "behind you"
        where = f"{dist[anchor]:.1f} m from the {name} ({'on your ' + side if side != 'behind you' else side})"
    if faced == anchor:
        return where
    return f"{where}, facing the {objects[faced].label}"
