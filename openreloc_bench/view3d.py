"""A method's map in 3D as a plotly figure: what ``openreloc-bench view`` writes as one HTML file.

The figure holds what the map keeps in 3D (:class:`~openreloc_bench.methods.MapPoints`: its points,
coloured per group, e.g. per landmark or per mapping frame; the groups the method set aside in grey),
its cameras, optionally the scene's mapping path and a run's query cameras: each estimate joined to the
true camera by a line, green within :data:`RECALL_RADIUS_M` and red beyond it. Points are subsampled to
a cap so that a big map stays quick to draw; an estimate far outside everything else is drawn at the
edge of the view (and counted in the legend) instead of shrinking the map to a dot.

    fig = map_figure(method.map_points(map_dir), mapping=scene.sequence("mapping").poses,
                     true_poses=gt, estimates=read_results("poses.txt"))
    fig.write_html("map.html", include_plotlyjs=True)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.methods import MapPoints

if TYPE_CHECKING:
    import plotly.graph_objects as go

RECALL_RADIUS_M = 0.5
"""An estimate within this distance of the true camera is drawn green (the benchmark's recall@50cm)."""
DEFAULT_MAX_POINTS = 60_000
"""Map points drawn at most (each group keeps a share proportional to its size, at least one point)."""
VIEW_MARGIN_M = 1.0
"""How far beyond the map, the cameras and the true query cameras the view reaches; estimates beyond
that are drawn at its edge."""
MAX_MAPPING_FRUSTUMS = 12
"""Mapping cameras drawn as frustums (evenly spaced along the path; the path itself shows every frame)."""

POINTS_GROUP, MUTED_GROUP = "points", "muted"
MUTED_COLOR = "rgb(170,170,170)"
WITHIN_COLOR, BEYOND_COLOR, TRUE_COLOR, MISSED_COLOR = "rgb(34,160,70)", "rgb(215,40,40)", "rgb(20,20,20)", "gray"


def point_strides(counts: Sequence[int], cap: int) -> list[int]:
    """Per group, the stride ``points[::stride]`` that keeps the total near ``cap``: every point when
    all of them fit, else a share proportional to each group's size (never less than one point)."""
    total = sum(counts)
    if total <= cap:
        return [1] * len(counts)
    return [max(1, math.ceil(n / max(1, n * cap // total))) for n in counts]


def frustum_lines(
    T_wc: np.ndarray, K: np.ndarray, width: int, height: int, depth: float
) -> tuple[list[float | None], ...]:
    """x, y, z lists of line strips (``None`` between cameras) drawing each camera of ``T_wc`` (N, 4, 4)
    as a pyramid ``depth`` metres deep: its apex at the centre, its base the image's corners."""
    corners = np.array([[0, 0], [width, 0], [width, height], [0, height]], dtype=np.float64)
    rays = np.c_[corners, np.ones(4)] @ np.linalg.inv(K).T
    base_c = rays / rays[:, 2:3] * depth  # (4, 3) in the camera frame
    xs: list[float | None] = []
    ys: list[float | None] = []
    zs: list[float | None] = []
    for T in np.asarray(T_wc).reshape(-1, 4, 4):
        c = T[:3, 3]
        p = base_c @ T[:3, :3].T + c
        # one strip: the base's four edges, then the four edges to the apex (p2-p3 is drawn twice)
        for q in (p[0], p[1], p[2], p[3], p[0], c, p[1], p[2], c, p[3]):
            xs.append(float(q[0]))
            ys.append(float(q[1]))
            zs.append(float(q[2]))
        xs.append(None)
        ys.append(None)
        zs.append(None)
    return xs, ys, zs


def _palette() -> list[str]:
    from plotly.colors import qualitative

    return list(qualitative.Dark24) + list(qualitative.Light24)


def point_traces(mp: MapPoints, max_points: int = DEFAULT_MAX_POINTS) -> tuple[list[go.Scatter3d], np.ndarray]:
    """The map's points as two traces, each point coloured by its group with the group's hover text: the
    groups drawn in colour, and the muted ones in grey; and the (N, 3) points drawn."""
    import plotly.graph_objects as go

    groups, inverse = np.unique(mp.group, return_inverse=True)
    members = np.split(np.argsort(inverse, kind="stable"), np.cumsum(np.bincount(inverse, minlength=len(groups)))[:-1])
    strides = point_strides([len(m) for m in members], max_points)
    keep = np.sort(np.concatenate([m[::s] for m, s in zip(members, strides)] or [np.zeros(0, np.int64)]))
    colors = _palette()
    traces, drawn = [], []
    name, muted_name, _ = mp.names
    for muted in (False, True):
        rows = keep[np.isin(mp.group[keep], list(mp.muted)) == muted]
        if not len(rows):
            continue
        pts, g = np.asarray(mp.points, np.float64)[rows].reshape(-1, 3), mp.group[rows]
        shown = [k for k in groups if (k in mp.muted) == muted]
        rank = {k: i for i, k in enumerate(shown)}
        traces.append(
            go.Scatter3d(
                x=pts[:, 0],
                y=pts[:, 1],
                z=pts[:, 2],
                mode="markers",
                marker={
                    "size": 1.5 if muted else 2,
                    "color": MUTED_COLOR if muted else [colors[rank[k] % len(colors)] for k in g],
                    "opacity": 0.35 if muted else 0.8,
                },
                name=f"{muted_name if muted else name} ({len(shown)})",
                legendgroup=MUTED_GROUP if muted else POINTS_GROUP,
                text=[mp.labels.get(int(k), str(k)) for k in g],
                hovertemplate="%{text}<extra></extra>",
            )
        )
        drawn.append(pts)
    return traces, (np.concatenate(drawn) if drawn else np.zeros((0, 3)))


def _cameras(
    T_wc: np.ndarray,
    K: np.ndarray,
    size: tuple[int, int],
    depth: float,
    name: str,
    color: str,
    group: str,
    hover: Sequence[str],
    width: float = 2.0,
) -> list[go.Scatter3d]:
    """A set of cameras: their frustums (the legend entry) and a marker at each centre to hover on."""
    import plotly.graph_objects as go

    T_wc = np.asarray(T_wc).reshape(-1, 4, 4)
    x, y, z = frustum_lines(T_wc, K, size[0], size[1], depth)
    c = T_wc[:, :3, 3]
    return [
        go.Scatter3d(
            x=x,
            y=y,
            z=z,
            mode="lines",
            line={"color": color, "width": width},
            name=name,
            legendgroup=group,
            hoverinfo="skip",
        ),
        go.Scatter3d(
            x=c[:, 0],
            y=c[:, 1],
            z=c[:, 2],
            mode="markers",
            marker={"size": 3, "color": color},
            name=name,
            legendgroup=group,
            showlegend=False,
            text=list(hover),
            hovertemplate="%{text}<extra></extra>",
        ),
    ]


def query_errors(true_poses: dict[str, np.ndarray], estimates: dict[str, np.ndarray]) -> dict[str, tuple[float, float]]:
    """Per estimated query, (translation error in metres, rotation error in degrees) against its true pose."""
    return {
        n: (
            float(geometry.translation_error(true_poses[n], T)),
            float(geometry.rotation_error(true_poses[n], T)),
        )
        for n, T in estimates.items()
    }


def map_figure(
    mp: MapPoints,
    mapping: np.ndarray | None = None,
    true_poses: dict[str, np.ndarray] | None = None,
    estimates: dict[str, np.ndarray] | None = None,
    max_points: int = DEFAULT_MAX_POINTS,
    title: str | None = None,
) -> go.Figure:
    """The 3D figure of a map's points ``mp``.

    ``mapping``: (N, 4, 4) T_wc of the scene's mapping frames (the path, a few frustums). ``true_poses``:
    query name -> true T_wc, for every query of the split; ``estimates``: query name -> estimated T_wc,
    for the queries that returned a pose (names of ``true_poses``). Queries that returned none are drawn
    at their true camera, in grey.
    """
    import plotly.graph_objects as go

    estimates = estimates or {}
    true_poses = true_poses or {}
    unknown = sorted(set(estimates) - set(true_poses))
    if unknown:
        raise ValueError(f"estimate of '{unknown[0]}' has no true pose")
    traces, extent_pts = point_traces(mp, max_points)
    extent = [extent_pts]
    if len(mp.cameras):
        T, name = np.asarray(mp.cameras).reshape(-1, 4, 4), mp.names[2]
        hover = list(mp.camera_labels) or [f"{name} {k}" for k in range(len(T))]
        traces += _cameras(T, mp.K, mp.size, 0.15, f"{name} ({len(T)})", "rgb(31,119,180)", "rf", hover, 1.5)
        extent.append(T[:, :3, 3])
    if mapping is not None and len(mapping):
        mapping = np.asarray(mapping).reshape(-1, 4, 4)
        c = mapping[:, :3, 3]
        traces.append(
            go.Scatter3d(
                x=c[:, 0],
                y=c[:, 1],
                z=c[:, 2],
                mode="lines+markers",
                line={"color": "rgb(255,127,14)", "width": 3},
                marker={"size": 2, "color": "rgb(255,127,14)"},
                name=f"mapping path ({len(c)} frames)",
                legendgroup="mapping",
                text=[f"mapping frame {i}" for i in range(len(c))],
                hovertemplate="%{text}<extra></extra>",
            )
        )
        every = np.unique(np.linspace(0, len(c) - 1, min(MAX_MAPPING_FRUSTUMS, len(c))).round().astype(int))
        frust = _cameras(
            mapping[every], mp.K, mp.size, 0.25, "mapping cameras", "rgb(255,127,14)", "mapping", [], width=2.0
        )
        frust[0].showlegend = False
        traces.append(frust[0])  # the centres are on the path already
        extent.append(c)
    traces += _query_traces(mp, true_poses, estimates, extent)
    fig = go.Figure(traces)
    fig.update_layout(
        title={"text": title or default_title(mp, true_poses, estimates), "font": {"size": 14}},
        template="plotly_white",
        margin={"l": 0, "r": 0, "t": 40, "b": 0},
        legend={"itemsizing": "constant"},
        scene={
            "aspectmode": "data",
            "xaxis": {"title": {"text": "x (m)"}},
            "yaxis": {"title": {"text": "y (m)"}},
            "zaxis": {"title": {"text": "z (m)"}},
        },
    )
    return fig


def _query_traces(
    mp: MapPoints, true_poses: dict[str, np.ndarray], estimates: dict[str, np.ndarray], extent: list[np.ndarray]
) -> list[go.Scatter3d]:
    import plotly.graph_objects as go

    if not true_poses:
        return []
    names = sorted(true_poses)
    T_true = np.stack([true_poses[n] for n in names])
    pts = np.concatenate([e.reshape(-1, 3) for e in [*extent, T_true[:, :3, 3]]])
    lo, hi = pts.min(axis=0) - VIEW_MARGIN_M, pts.max(axis=0) + VIEW_MARGIN_M
    errors = query_errors(true_poses, estimates)
    returned = [n for n in names if n in estimates]
    missed = [n for n in names if n not in estimates]
    traces = []
    for group, label, color, key, hover in (
        (returned, f"true cameras ({len(returned)} returned a pose)", TRUE_COLOR, "true", "{} (true)"),
        (missed, f"no pose returned ({len(missed)}, true cameras)", MISSED_COLOR, "missed", "{}: no pose returned"),
    ):
        if group:
            T = np.stack([true_poses[n] for n in group])
            traces += _cameras(T, mp.K, mp.size, 0.12, label, color, key, [hover.format(n) for n in group])
    for within in (True, False):
        group = [n for n in returned if (errors[n][0] < RECALL_RADIUS_M) == within]
        if not group:
            continue
        color = WITHIN_COLOR if within else BEYOND_COLOR
        T_est = np.stack([estimates[n] for n in group])
        c_est = T_est[:, :3, 3]
        drawn = np.clip(c_est, lo, hi)
        outside = np.any(drawn != c_est, axis=1)
        label = f"{'within' if within else 'beyond'} {RECALL_RADIUS_M * 100:.0f} cm"
        name = f"estimated, {label} ({len(group)})"
        if outside.any():
            name = f"estimated, {label} ({len(group)}; {int(outside.sum())} outside the view, drawn at its edge)"
        key = f"est-{'in' if within else 'out'}"
        inside = ~outside
        if inside.any():  # the estimated frustums of the estimates in view; the others are a marker
            x, y, z = frustum_lines(T_est[inside], mp.K, mp.size[0], mp.size[1], 0.12)
            traces.append(
                go.Scatter3d(
                    x=x,
                    y=y,
                    z=z,
                    mode="lines",
                    line={"color": color, "width": 2},
                    name=name,
                    legendgroup=key,
                    showlegend=False,
                    hoverinfo="skip",
                )
            )
        lx: list[float | None] = []
        ly: list[float | None] = []
        lz: list[float | None] = []
        for n, p in zip(group, drawn):
            t = true_poses[n][:3, 3]
            lx += [float(p[0]), float(t[0]), None]
            ly += [float(p[1]), float(t[1]), None]
            lz += [float(p[2]), float(t[2]), None]
        traces.append(
            go.Scatter3d(
                x=lx,
                y=ly,
                z=lz,
                mode="lines",
                line={"color": color, "width": 3, "dash": "solid" if within else "dash"},
                name=name,
                legendgroup=key,
                showlegend=False,
                hoverinfo="skip",
            )
        )
        hover = []
        for n, c, out in zip(group, c_est, outside):
            te, re = errors[n]
            text = f"{n} (estimate)<br>error {te * 100:.1f} cm, {re:.1f}°"
            if out:
                text += f"<br>estimated at ({c[0]:.1f}, {c[1]:.1f}, {c[2]:.1f}) m, outside the view"
            hover.append(text)
        traces.append(
            go.Scatter3d(
                x=drawn[:, 0],
                y=drawn[:, 1],
                z=drawn[:, 2],
                mode="markers",
                marker={"size": 4, "color": color, "symbol": ["x" if o else "circle" for o in outside]},
                name=name,
                legendgroup=key,
                text=hover,
                hovertemplate="%{text}<extra></extra>",
            )
        )
    return traces


def default_title(mp: MapPoints, true_poses: dict[str, np.ndarray], estimates: dict[str, np.ndarray]) -> str:
    """One line: the map's content and, with queries, how many returned a pose and the recall@50cm."""
    text = mp.summary or f"{len(mp.points)} points, {len(mp.cameras)} cameras"
    if true_poses:
        errors = query_errors(true_poses, estimates)
        within = sum(te < RECALL_RADIUS_M for te, _ in errors.values())
        text += (
            f"; {len(estimates)}/{len(true_poses)} queries returned a pose, {within} within "
            f"{RECALL_RADIUS_M * 100:.0f} cm (recall {within / len(true_poses):.0%})"
        )
    return text
