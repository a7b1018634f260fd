"""MuJoCo backend: exact metric depth, instance ids, OpenCV pose convention, lighting, moving instances."""

from __future__ import annotations

import numpy as np
import pytest

from generators.layout import Instance, Layout, Light, Room
from generators.layout.model import box_mesh, make_part
from generators.render import create_renderer, mujoco_backend
from generators.render.mujoco_backend import MAX_MATERIALS, build_mjcf
from openreloc_bench import geometry
from openreloc_bench.errors import ConfigError

W, H = 160, 120


def _box(iid: int, lo, hi, colour: str, category: str, structural: bool) -> Instance:
    return Instance(
        id=iid,
        category=category,
        parts=[make_part([box_mesh(lo, hi)], "plaster", colour, iid)],
        transform=np.eye(4),
        structural=structural,
        room="r",
        floor=0,
    )


def _box_room_layout() -> Layout:
    """A 4 x 5 m closed room with one 1 x 0.5 x 1 m box whose front face is at y = 3.5."""
    insts = [
        _box(1, (0, 0, -0.1), (4, 5, 0), "brown", "floor", True),
        _box(2, (-0.1, 0, 0), (0, 5, 2.7), "white", "wall", True),
        _box(3, (4, 0, 0), (4.1, 5, 2.7), "white", "wall", True),
        _box(4, (0, -0.1, 0), (4, 0, 2.7), "cream", "wall", True),
        _box(5, (0, 5, 0), (4, 5.1, 2.7), "pink", "wall", True),
        _box(6, (0, 0, 2.7), (4, 5, 2.8), "white", "ceiling", True),
        _box(7, (1.5, 3.5, 0), (2.5, 4.0, 1.0), "red", "box", False),
    ]
    return Layout(
        [Room("r", "living", 0, (0, 0, 4, 5), 0.0, 2.7)],
        [],
        [Light(np.array([2, 2.5, 2.3]), "r", 0)],
        insts,
        (4.0, 5.0),
        [0.0],
        2.7,
    )


@pytest.fixture(scope="module")
def box_room():
    r = create_renderer(_box_room_layout(), "mujoco", W, H)
    yield r
    r.close()


K = geometry.intrinsics_from_fov(W, H, 60.0)
POSES = [
    geometry.look_at([2, 0.5, 1.0], [2, 3.5, 0.5]),
    geometry.look_at([0.6, 1.0, 1.6], [2.0, 3.75, 0.5]),
    geometry.look_at([3.5, 2.0, 0.4], [1.8, 3.6, 0.7]),
]


@pytest.mark.parametrize("pose", range(len(POSES)))
def test_exact_depth_on_known_geometry(box_room, pose: int) -> None:
    T = POSES[pose]
    rgb, depth, inst = box_room.render(T, K, W, H)
    assert rgb.shape == (H, W, 3) and rgb.dtype == np.uint8
    assert depth.dtype == np.float32 and inst.dtype == np.int32
    assert (depth > 0).all()  # a closed room: every pixel hits a surface
    floor = geometry.depth_to_points(depth, K, T, inst == 1)
    assert len(floor) > 100 and np.abs(floor[:, 2]).max() < 1e-4
    box = geometry.depth_to_points(depth, K, T, inst == 7)
    assert len(box) > 50
    lo, hi = np.array([1.5, 3.5, 0.0]), np.array([2.5, 4.0, 1.0])
    assert np.all(box >= lo - 1e-4) and np.all(box <= hi + 1e-4)
    # every box pixel lies on one of the box faces (metric error of unprojection, not just inside the box)
    face_dist = np.min(np.abs(np.concatenate([box - lo, box - hi], axis=1)), axis=1)
    assert face_dist.max() < 1e-4


def test_a_stored_compiled_scene_renders_the_same(box_room, tmp_path, monkeypatch) -> None:
    """The second renderer of a layout reads the compiled model (no texture drawn) and draws the same
    pixels; a damaged file is compiled again."""
    stored = tmp_path / "room.mjb"
    first = create_renderer(_box_room_layout(), "mujoco", W, H, compiled=stored)
    first.close()
    assert stored.is_file() and stored.with_suffix(".npy").is_file()

    def no_compile(*args, **kwargs):
        raise AssertionError("compiled the scene again")

    with monkeypatch.context() as m:
        m.setattr(mujoco_backend, "build_mjcf", no_compile)
        again = create_renderer(_box_room_layout(), "mujoco", W, H, compiled=stored)
    try:
        for got, want in zip(again.render(POSES[1], K, W, H), box_room.render(POSES[1], K, W, H)):
            assert np.array_equal(got, want)
    finally:
        again.close()
    stored.write_bytes(b"damaged")
    monkeypatch.chdir(tmp_path)  # MuJoCo logs the bad header to MUJOCO_LOG.TXT in the working folder
    create_renderer(_box_room_layout(), "mujoco", W, H, compiled=stored).close()
    assert stored.stat().st_size > 1000


def test_colour_only_rendering_matches_the_full_render(box_room) -> None:
    rgb, depth, _ = box_room.render(POSES[1], K, W, H)
    rgb2, depth2 = box_room.render_color(POSES[1], K, W, H, depth=True)
    assert np.array_equal(rgb, rgb2) and np.array_equal(depth, depth2)
    K2 = geometry.intrinsics_from_fov(W // 2, H // 2, 60.0)
    rgb3, none = box_room.render_color(POSES[1], K2, W // 2, H // 2)
    assert rgb3.shape == (H // 2, W // 2, 3) and none is None


def test_opencv_convention(box_room) -> None:
    """The box centre projects where geometry.project says (x right, y down, z forward)."""
    T = POSES[0]
    _, _, inst = box_room.render(T, K, W, H)
    uv, z = geometry.project(K, T, np.array([[2.0, 3.5, 0.5], [1.5, 3.5, 0.95], [2.5, 3.5, 0.05]]))
    assert (z > 0).all()
    for u, v in np.round(uv).astype(int):
        assert inst[v, u] == 7
    v_top = np.nonzero((inst == 7).any(axis=1))[0].min()
    uv_top, _ = geometry.project(K, T, np.array([[2.0, 3.5, 1.0]]))
    assert abs(v_top - uv_top[0, 1]) <= 1.0


def test_lighting_and_displacement(box_room) -> None:
    T = POSES[0]
    bright, _, _ = box_room.render(T, K, W, H)
    box_room.set_lighting(0.3, (1.0, 0.7, 0.5))
    dim, depth_dim, _ = box_room.render(T, K, W, H)
    box_room.set_lighting(1.0)
    assert dim.mean() < 0.6 * bright.mean()
    assert dim[..., 2].mean() < dim[..., 0].mean()  # warm tint
    box_room.set_instance_pose(7, geometry.make_pose(np.eye(3), [0.5, 0.0, 0.0]))
    _, depth, inst = box_room.render(T, K, W, H)
    moved = geometry.depth_to_points(depth, K, T, inst == 7)
    box_room.set_instance_pose(7, np.eye(4))
    assert moved[:, 0].min() > 2.0 - 1e-4 and moved[:, 0].max() < 3.0 + 1e-4
    again, _, _ = box_room.render(T, K, W, H)
    assert np.array_equal(again, bright)  # deterministic and fully restored


def test_bad_inputs(box_room) -> None:
    with pytest.raises(ValueError):
        box_room.render(POSES[0], K, 2 * W, 2 * H)
    with pytest.raises(geometry.GeometryError):
        box_room.render(np.eye(4) * 2, K, W, H)
    with pytest.raises(ConfigError):
        create_renderer(box_room.layout, "vulkan")


def test_culling_is_exact(monkeypatch) -> None:
    """Frustum + portal culling must not change a single pixel (multi-room and multi-floor scenes)."""
    from generators.layout import build_layout
    from generators.spec import SceneSpec
    from generators.trajectories import mapping_trajectory

    for spec in (
        SceneSpec(name="c", kind="multi-room", seed=31, rooms=5, objects_per_room=6, width=W, height=H),
        SceneSpec(name="d", kind="multi-floor", seed=32, rooms=2, floors=2, objects_per_room=5, width=W, height=H),
    ):
        layout = build_layout(spec)
        poses = mapping_trajectory(layout, spec)[::25]
        with create_renderer(layout, "mujoco", W, H) as r:
            culled = [r.render(T, K, W, H) for T in poses]
            drawn = [(r._cull(T, K, W, H), (r.model.geom_rgba[:, 3] > 0).mean())[1] for T in poses]
            monkeypatch.setattr(r._culler, "_visible_rooms", lambda *a: None)
            for T, (rgb, depth, inst) in zip(poses, culled):
                rgb2, depth2, inst2 = r.render(T, K, W, H)
                assert np.array_equal(rgb, rgb2) and np.array_equal(inst, inst2) and np.array_equal(depth, depth2)
        assert np.mean(drawn) < 0.5  # and it actually culls


def _many_boxes(n: int, colours: tuple[str, ...]) -> Layout:
    """n small boxes in a row, cycling through ``colours``, every part with its own texture seed."""
    insts = [_box(1, (0, 0, -0.1), (n * 0.1, 2, 0), "brown", "floor", True)]
    insts += [
        _box(i + 2, (0.1 * i, 1.0, 0), (0.1 * i + 0.05, 1.05, 0.05), colours[i % len(colours)], "box", False)
        for i in range(n)
    ]
    return Layout(
        [Room("r", "living", 0, (0, 0, n * 0.1, 2), 0.0, 2.7)],
        [],
        [Light(np.array([1, 1, 2.3]), "r", 0)],
        insts,
        (n * 0.1, 2.0),
        [0.0],
        2.7,
    )


@pytest.mark.parametrize("parts", [MAX_MATERIALS, MAX_MATERIALS + 100])
def test_scene_at_and_beyond_mujocos_material_limit_renders(parts: int) -> None:
    """A large house has more textured parts than MuJoCo accepts materials: texture seeds are folded per
    (material, colour) so the model fits, and every instance still renders with its own id."""
    layout = _many_boxes(parts - 1, ("red", "blue", "green"))  # plus the floor
    r = create_renderer(layout, "mujoco", W, H)
    try:
        assert r.model.nmat <= MAX_MATERIALS
        assert (r.model.nmat == parts) == (parts <= MAX_MATERIALS)
        T = geometry.look_at([0.5, 0.2, 0.4], [0.5, 1.0, 0.0])
        _, depth, inst = r.render(T, K, W, H)
        assert (depth > 0).any() and len(np.unique(inst)) > 3
    finally:
        r.close()


@pytest.mark.parametrize("limit, expected", [(100, 13), (6, 5), (3, 3)])
def test_texture_seeds_fold_only_beyond_the_limit(monkeypatch, limit: int, expected: int) -> None:
    """Within the limit every part keeps its own texture (scenes render as before); beyond it, the most
    seed variants per (material, colour) that fit."""
    monkeypatch.setattr(mujoco_backend, "MAX_MATERIALS", limit)
    xml = build_mjcf(_many_boxes(12, ("red", "blue")), W, H)[0]
    assert xml.count("<material ") == expected


def test_more_colours_than_materials_is_a_clear_error(monkeypatch) -> None:
    monkeypatch.setattr(mujoco_backend, "MAX_MATERIALS", 2)
    with pytest.raises(ConfigError, match="distinct"):
        build_mjcf(_many_boxes(12, ("red", "blue")), W, H)
