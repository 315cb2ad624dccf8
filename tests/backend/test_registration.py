"""The nodes registered scan to scan: nearby nodes' scans matched to each other are surer of
their relative poses than a front end that jitters, and the front end's steps that no match
backs are the ones a loop may bend."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from pfslam.backend.nodes import frame_scans, select_nodes
from pfslam.backend.registration import local_poses, match_spans, register_steps
from pfslam.backend.search import search_stride
from pfslam.backend.settings import BackendSettings
from pfslam.config import GraphConfig, SlamConfig
from pfslam.eval.metrics import associate
from pfslam.geometry import compose, relative


def test_scan_matches_are_surer_than_a_jittering_front_end(office_sim, office_log) -> None:
    """The office walk's first 60 s with the truth as the front end, each pose jittered by 2 cm
    and 0.3 deg: the matches of nearby nodes land within a few millimetres of the true relative
    poses (the jittered front end: centimetres), each span's matches as sure as they claim."""
    cfg = SlamConfig()
    frames = office_log.frames[:2400]
    t = np.array([f.t for f in frames])
    i_f, i_t = associate(t, office_sim.t)
    assert len(i_f) == len(frames)
    truth = office_sim.truth[i_t]
    rng = np.random.default_rng(0)
    jittered = compose(truth, rng.normal(0, [0.02, 0.02, np.deg2rad(0.3)], truth.shape))
    nodes = select_nodes(frames, jittered, BackendSettings.of(cfg))
    true_nodes = truth[nodes.scan]
    with ThreadPoolExecutor(2) as pool:
        own = np.ones(len(nodes), dtype=bool)
        steps = register_steps(nodes.poses, own, None, nodes.information(), frame_scans(frames, nodes, BackendSettings.of(cfg)),
                               nodes.dense, cfg.graph, pool)  # fmt: skip
    m = steps.matched
    assert set((steps.j - steps.i)[m].tolist()) == set(match_spans(cfg.graph)) == {1, 4, 16}
    assert m[steps.j - steps.i == 1].mean() > 0  # (the front end's steps are there too, unmatched)
    k = np.nonzero(m & (steps.j - steps.i == 1))[0]
    assert len(k) > 0.9 * (len(nodes) - 1)
    err = relative(relative(true_nodes[steps.i[k]], true_nodes[steps.j[k]]), steps.z[k])
    front = relative(
        relative(true_nodes[steps.i[k]], true_nodes[steps.j[k]]),
        relative(nodes.poses[steps.i[k]], nodes.poses[steps.j[k]]),
    )
    assert np.median(np.hypot(err[:, 0], err[:, 1])) < 0.25 * np.median(np.hypot(front[:, 0], front[:, 1]))
    assert np.median(np.abs(err[:, 2])) < 0.25 * np.median(np.abs(front[:, 2]))
    chi2 = np.einsum("ki,kij,kj->k", err, steps.info[k], err)
    assert np.median(chi2) < 2 * 2.366  # about as sure as they are (a chi^2 of 3 has median 2.37)
    # placed by the steps alone, the nodes' relative poses within a submap are the matches'
    placed = local_poses(nodes.poses, steps, 1)
    a, b = np.arange(len(nodes) - 20), np.arange(20, len(nodes))
    e_placed = relative(relative(true_nodes[a], true_nodes[b]), relative(placed[a], placed[b]))
    e_front = relative(relative(true_nodes[a], true_nodes[b]), relative(nodes.poses[a], nodes.poses[b]))
    assert np.median(np.hypot(*e_placed[:, :2].T)) < 0.5 * np.median(np.hypot(*e_front[:, :2].T))


def test_a_step_no_match_backs_is_looser_by_a_slip() -> None:
    """Two consecutive nodes whose scans cannot be matched (no hits): the front end's step
    between them is as unsure as a missed turn."""
    from pfslam.backend.registration import Steps, slipping

    info = np.tile(np.diag([1e4, 1e4, 1e4]), (3, 1, 1))
    front = Steps(np.array([0, 1, 0]), np.array([1, 2, 2]), np.zeros((3, 3)), info, np.zeros(3, bool))
    out = slipping(front, {(0, 1)}, GraphConfig())  # (0, 1) was matched, (1, 2) was not
    sd = np.sqrt(np.diagonal(np.linalg.inv(out.info), axis1=1, axis2=2))
    assert sd[0, 2] == np.sqrt(1e-4) and sd[2, 2] == np.sqrt(1e-4)  # backed, and the span of two
    assert np.rad2deg(sd[1, 2]) > 0.9 * GraphConfig().slip_deg


def test_the_search_samples_a_long_log_and_not_a_short_one() -> None:
    c = GraphConfig()
    assert search_stride(150, c) == 1 and search_stride(900, c) == 3 and search_stride(2000, c) == 7
    assert search_stride(2000, GraphConfig(search_every=2)) == 2
