"""The one-line placement: distance to the nearest matched object, and the object faced."""

from __future__ import annotations

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.openreloc.explain import PlacedObject, explain_pose


def box(center, half, category=None, phrase=None) -> PlacedObject:
    c = np.array(center, float)
    return PlacedObject(c, c - half, c + half, category, phrase)


def test_in_front_of_the_nearest_object_facing_the_one_on_axis() -> None:
    T = geometry.look_at([0, 0, 1.5], [5, 0, 1.0])  # looking along +x
    sofa = box([2.3, 0.4, 1.2], 0.5, "sofa", "a blue sofa")  # box face 1.8 m ahead
    table = box([4.0, 0.0, 0.4], 0.4, "dining_table")
    assert explain_pose(T, [table, sofa]) == "1.8 m in front of the blue sofa, facing the dining_table"


def test_side_objects_and_unknown_categories_use_the_phrase() -> None:
    T = geometry.look_at([0, 0, 1.5], [5, 0, 1.5])
    lamp = box([0.0, 1.2, 1.5], 0.1, None, "a white lamp")  # on the camera's left (+y when facing +x)
    tv = box([4.0, 0.0, 1.5], 0.3, None, "a black television")
    assert explain_pose(T, [lamp, tv]) == "1.1 m from the white lamp (on your left), facing the black television"
    # a phrase that does not name the known category gives way to the category
    assert box([0, 0, 0], 0.1, "chair", "a red table").label == "chair"
    assert explain_pose(T, []) == ""
