import numpy as np

from baselines.goreloc.ellipsoid import dual_quadrics, ellipses_from_boxes
from baselines.goreloc.localize import Frame, MapGeometry, RansacConfig, draw_matchings, p3p_poses
from openreloc_bench import geometry


def test_p3p_recovers_a_known_pose_from_exact_correspondences():
    K = geometry.intrinsics(500.0, 500.0, 320.0, 240.0)
    T_wc = geometry.look_at([2.5, -3.0, 1.6], [0.0, 0.0, 0.8])
    X = np.array([[0.5, 0.2, 0.4], [-0.8, 0.6, 1.2], [0.3, -0.9, 0.9]])
    uv, z = geometry.project(K, T_wc, X)
    assert (z > 0).all()
    poses = p3p_poses(X, uv, K)
    assert 1 <= len(poses) <= 4
    t_err, r_err = geometry.pose_errors(np.repeat(T_wc[None], len(poses), 0), np.array(poses))
    assert t_err.min() < 1e-6 and r_err.min() < 1e-4


def test_matchings_agree_on_adjacency_whatever_the_node_order():
    # frame: a path 0 - 1 - 2; map: a path 10 - 11 - 12 and, for each node, a decoy that breaks it
    frame_adj = np.zeros((3, 3), bool)
    frame_adj[[0, 1], [1, 2]] = frame_adj[[1, 2], [0, 1]] = True
    n = 16
    map_adj = np.zeros((n, n), bool)
    map_adj[[10, 11], [11, 12]] = map_adj[[11, 12], [10, 11]] = True
    map_adj[13, [10, 11, 12]] = map_adj[[10, 11, 12], 13] = True  # decoy of node 0: linked to 12 as well
    mu, S = ellipses_from_boxes(np.array([[0, 0, 10, 10]] * 3))
    frame = Frame(np.zeros((3, 4)), mu, S, frame_adj, [np.array([10, 13]), np.array([11, 14]), np.array([12, 15])])
    world = MapGeometry(
        dual_quadrics(np.zeros((n, 3)), np.repeat(np.eye(3)[None], n, 0), np.ones((n, 3))),
        np.zeros((n, 3)),
        map_adj,
        np.ones(n),
    )
    cfg = RansacConfig()
    for order in ([0, 1, 2], [2, 1, 0], [1, 2, 0]):
        found = draw_matchings(frame, world, np.array(order), cfg, np.random.default_rng(0))
        assert found and all(len(m) == 3 for m in found)
        for m in found:
            for u, o in m:
                for v, p in m:
                    if u != v:
                        assert frame_adj[u, v] == map_adj[o, p]
        assert {frozenset(m) for m in found} == {frozenset({(0, 10), (1, 11), (2, 12)})}
