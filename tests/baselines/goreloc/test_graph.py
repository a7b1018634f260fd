import numpy as np

from baselines.goreloc.graph import (
    frame_descriptors,
    knn_adjacency,
    label_frequencies,
    map_descriptors,
    match_candidates,
)


def test_knn_adjacency_is_symmetric_and_has_k_neighbours_at_least():
    pts = np.random.default_rng(0).uniform(size=(12, 2))
    adj = knn_adjacency(pts, 3)
    assert (adj == adj.T).all() and not adj.diagonal().any() and (adj.sum(1) >= 3).all()
    assert not knn_adjacency(pts[:1], 5).any() and knn_adjacency(pts[:3], 5).sum() == 6  # k = min(k, n - 1)


def test_frame_descriptor_weights_rare_labels_more():
    labels = np.array([1, 1, 1, 2])  # node 3 is linked to everyone
    adj = np.zeros((4, 4), bool)
    adj[3, :3] = adj[:3, 3] = True
    adj[0, 1] = adj[1, 0] = True
    d = frame_descriptors(labels, adj)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
    assert d[3, 1] == 1.0 and d[3, 2] == 0.0  # three label-1 neighbours, each 1 - 3/4
    assert np.isclose(d[0, 1] / d[0, 2], 0.25 / 0.75)  # a label-1 (share 3/4) and a label-2 (share 1/4) neighbour


def test_single_label_objects_count_in_map_descriptors():
    counts = np.zeros((3, 80), int)
    counts[0, 5], counts[1, 7], counts[2, [7, 9]] = 4, 2, [1, 3]
    freq = label_frequencies(counts)
    assert freq[0, 5] == 1.0 and np.allclose(freq[2, [7, 9]], [0.25, 0.75])
    adj = np.array([[0, 1, 1], [1, 0, 0], [1, 0, 0]], bool)
    d = map_descriptors(freq, adj)
    assert d[1, 5] == 1.0  # its single-label neighbour (GOReloc's code would leave this empty)
    assert np.isclose(np.linalg.norm(d[0]), 1.0) and d[0, 7] > d[0, 9]


def test_candidates_share_the_label_pass_the_cosine_and_are_ranked():
    map_labels = np.array([3, 3, 3, 3, 4])
    map_desc = np.eye(80)[[0, 1, 2, 0, 0]] * 1.0
    map_desc[3] = (np.eye(80)[0] + np.eye(80)[1]) / np.sqrt(2)
    frame_desc = np.eye(80)[[0, 5]]
    cands = match_candidates(np.array([3, 3]), frame_desc, map_labels, map_desc, 0.01, 3)
    assert cands[0].tolist() == [0, 3]  # same label, cosine > 0.01, best first; node 4 has another label
    assert cands[1].tolist() == []
