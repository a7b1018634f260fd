"""What is wrong with a 3D instance map: precision / recall and each object's error, by object size.

Every true object (points of its box, :func:`box_point_labels`) is, against the predicted
instances:
- ``found``: one instance has IoU >= 0.5 with it;
- ``split``: instances lying mostly (>= half their points) inside it cover at least half of it, but
  none well enough: the map holds it in pieces;
- ``merged``: one instance holds at least half of it but lies mostly elsewhere: it was joined to
  something else;
- ``missed``: neither (its points are unassigned or scattered).
Every predicted instance without a match is a ``fragment`` (mostly inside one object), a ``merge``
(spread over objects) or ``background`` (mostly on points of no object).
Sizes: the diagonal of the object's points, small < 0.5 m <= medium < 1.5 m <= large.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from openreloc_bench.data.scene import ObjectInfo
from openreloc_bench.reconstruction.incidence import sets_matrix

SIZE_BINS_M = (0.5, 1.5)
SIZES = ("small", "medium", "large")
OBJECT_ERRORS = ("found", "split", "merged", "missed")
INSTANCE_ERRORS = ("matched", "fragment", "merge", "background")


def instance_report(points: np.ndarray, pred: dict[int, np.ndarray], truth: dict[int, np.ndarray]) -> dict[str, Any]:
    """Precision / recall at IoU 0.5 and 0.25 and the error classes above (counts per size)."""
    n = len(points)
    P, G = sets_matrix(list(pred.values()), n), sets_matrix(list(truth.values()), n)
    inter = (P @ G.T).toarray()
    p_size = np.asarray(P.sum(axis=1)).ravel()
    g_size = np.asarray(G.sum(axis=1)).ravel()
    iou = inter / np.maximum(p_size[:, None] + g_size[None, :] - inter, 1)
    out: dict[str, Any] = {"n_pred": len(pred), "n_gt": len(truth)}
    for t, suffix in ((0.5, ""), (0.25, "_25")):
        hit = iou >= t
        out[f"precision{suffix}"] = float(hit.any(axis=1).mean()) if len(pred) and len(truth) else 0.0
        out[f"recall{suffix}"] = float(hit.any(axis=0).mean()) if len(pred) and len(truth) else 0.0
    diag = np.array([float(np.linalg.norm(np.ptp(points[s], axis=0))) if len(s) else 0.0 for s in truth.values()])
    size = np.digitize(diag, SIZE_BINS_M)
    kind = [_object_error(iou[:, j], inter[:, j], p_size, g_size[j]) for j in range(len(truth))]
    out["objects"] = {
        e: {s: int(sum(k == e and size[j] == si for j, k in enumerate(kind))) for si, s in enumerate(SIZES)}
        for e in OBJECT_ERRORS
    }
    share = inter / np.maximum(p_size[:, None], 1)
    inst = [
        "matched"
        if len(truth) and iou[i].max() >= 0.5
        else "fragment"
        if len(truth) and share[i].max() >= 0.5
        else "merge"
        if share[i].sum() >= 0.5
        else "background"
        for i in range(len(pred))
    ]
    out["instances"] = {e: inst.count(e) for e in INSTANCE_ERRORS}
    return out


def _object_error(iou: np.ndarray, inter: np.ndarray, p_size: np.ndarray, g_size: float) -> str:
    if len(iou) == 0:
        return "missed"
    if iou.max() >= 0.5:
        return "found"
    inside = inter >= 0.5 * p_size
    if inter[inside].sum() >= 0.5 * g_size:
        return "split"
    if inter.max() >= 0.5 * g_size:
        return "merged"
    return "missed"


def boxed_objects(objects: dict[int, ObjectInfo]) -> dict[int, ObjectInfo]:
    """The objects with a box (``objects.json`` of generated scenes; converted real data has none)."""
    return {i: o for i, o in objects.items() if np.any(np.asarray(o.aabb[1]) > np.asarray(o.aabb[0]))}


def box_point_labels(points: np.ndarray, objects: dict[int, ObjectInfo], margin: float) -> np.ndarray:
    """(N,) ground-truth instance id per point from the objects' world boxes (0 = in no box).

    Independent of the instance masks, so both the oracle and the predicted tracks can be scored
    against it. A point strictly inside one or more boxes takes the smallest of them (a lamp on a
    table, a painting on a wall); a point only within ``margin`` of boxes (surface noise, thin walls
    and floors) takes the smallest of those. Loose boxes of rotated objects make it slightly coarse.
    """
    ids = np.array(sorted(objects))
    labels = np.zeros(len(points), np.int64)
    if len(ids) == 0 or len(points) == 0:
        return labels
    lo = np.array([objects[i].aabb[0] for i in ids], np.float64)
    hi = np.array([objects[i].aabb[1] for i in ids], np.float64)
    volume = np.prod(hi - lo + 2 * margin, axis=1)
    order = np.argsort(points[:, 0], kind="stable")  # each box tests only its slab of x
    xs = points[order, 0]
    best_strict = np.full(len(points), np.inf)
    best_loose = np.full(len(points), np.inf)
    lab_strict = np.zeros(len(points), np.int64)
    lab_loose = np.zeros(len(points), np.int64)
    for k in np.argsort(-volume):  # small boxes last, so they win ties of containment
        cand = order[np.searchsorted(xs, lo[k, 0] - margin) : np.searchsorted(xs, hi[k, 0] + margin, side="right")]
        p = points[cand]
        for m, best, lab in ((0.0, best_strict, lab_strict), (margin, best_loose, lab_loose)):
            idx = cand[np.all((p >= lo[k] - m) & (p <= hi[k] + m), axis=1)]
            idx = idx[volume[k] <= best[idx]]
            best[idx] = volume[k]
            lab[idx] = ids[k]
    return np.where(lab_strict > 0, lab_strict, lab_loose)
