"""Every loop checked against what the front end knew and against the other loops: a loop far
outside the path's uncertainty is refused whatever it scores; a loop slid along a corridor
disagrees with its true neighbours and is dropped, however well it matched; and the groups of
edges are weighed by how they held up."""

from __future__ import annotations

import numpy as np
import pytest

from pfslam.backend.consistency import (
    Chain,
    Paths,
    adjoint,
    confirmed,
    consistent,
    correlated,
    gate,
    to_world,
    world_difference,
)
from pfslam.backend.graph import PoseGraph, reweighted, variance_factors
from pfslam.geometry import compose, relative


def lap(n: int = 200, radius: float = 10.0) -> np.ndarray:
    """Poses round a circle, heading along it."""
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([radius * np.cos(a), radius * np.sin(a), a + np.pi / 2])


def paths(poses: np.ndarray, jitter_m: float = 0.02, jitter_deg: float = 0.5) -> Paths:
    travel = np.r_[0.0, np.cumsum(np.hypot(*np.diff(poses[:, :2], axis=0).T))]
    jitter = np.diag([jitter_m**2, jitter_m**2, np.deg2rad(jitter_deg) ** 2])
    return Paths(poses, travel, jitter, 0.005, np.deg2rad(0.05))


def test_world_perturbations_compose_as_the_poses_do() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(0, 3, (5, 3))
    d = rng.normal(0, 0.002, (5, 3))
    # a small perturbation in a pose's own frame is Ad(x) of it in the world's
    moved = compose(x, d)
    w = world_difference(moved, x)
    np.testing.assert_allclose(w, np.einsum("kij,kj->ki", adjoint(x), d), atol=5e-5)
    cov = np.tile(np.diag([1e-4, 4e-4, 1e-5]), (5, 1, 1))
    np.testing.assert_allclose(to_world(x, cov)[:, 2, 2], 1e-5)


def test_the_gate_refuses_a_loop_far_outside_the_path_whatever_it_says_it_is() -> None:
    poses = lap()
    p = paths(poses)
    a = np.array([0, 0, 0])
    i = np.array([190, 190, 190])
    true = relative(poses[0], poses[190])
    z = np.array([true, compose(true, [0.1, 0.05, 0.01]), compose(true, [3.0, 0.0, 0.0])])
    cov = np.tile(np.diag([1e-4, 1e-4, 1e-5]), (3, 1, 1))
    chi2 = gate(a, i, z, cov, poses, p)
    assert chi2[0] < 1e-6 and chi2[1] < 16.27 < chi2[2]  # 3 m off after 60 m: refused


def test_a_loop_slid_along_a_corridor_disagrees_with_its_neighbours_and_is_dropped() -> None:
    """Eight loops from nodes 150..164 to the submap at nodes 10..20, true to a centimetre; one
    more, its node's match slid 0.4 m along the path. The gate passes them all (after 50 m the
    path may have drifted that far); the pairs find the slid one out."""
    poses = lap()
    p = paths(poses)
    rng = np.random.default_rng(1)
    anchors = np.array([10, 10, 12, 12, 14, 14, 16, 16, 12])
    nodes = np.array([150, 152, 154, 156, 158, 160, 162, 164, 157])
    z = np.array(
        [compose(relative(poses[a], poses[i]), rng.normal(0, [0.01, 0.01, 0.002])) for a, i in zip(anchors, nodes)]
    )
    z[-1] = compose(z[-1], [0.4, 0.0, 0.0])
    cov = np.tile(np.diag([1e-4, 1e-4, np.deg2rad(0.1) ** 2]), (len(z), 1, 1))
    assert (gate(anchors, nodes, z, cov, poses, p) < 16.27).all()
    keep = consistent(anchors, nodes, z, cov, poses, p)
    assert keep.tolist() == [True] * 8 + [False]


def test_a_path_that_may_have_slipped_lets_a_large_closure_through() -> None:
    """Loops far from a front end that slipped where no scan match backs it: with the slips
    counted along the path between their nodes, two consistent closures agree with each other."""
    poses = lap()
    travel = np.r_[0.0, np.cumsum(np.hypot(*np.diff(poses[:, :2], axis=0).T))]
    jitter = np.diag([0.02**2, 0.02**2, np.deg2rad(0.5) ** 2])
    slips = np.r_[0.0, np.cumsum(np.isin(np.arange(len(poses) - 1), [170, 172, 175]))]
    strict = Paths(poses, travel, jitter, 0.005, np.deg2rad(0.05))
    slipping = Paths(poses, travel, jitter, 0.005, np.deg2rad(0.05), slips, 0.1, np.deg2rad(4.0))
    # the truth turned 8 degrees more between nodes 168 and 178 than the front end says
    truth = poses.copy()
    turn = np.r_[np.zeros(171), np.full(len(poses) - 171, np.deg2rad(8.0))]
    for k in range(171, len(poses)):
        truth[k] = compose(truth[170], compose([0, 0, turn[k]], relative(poses[170], poses[k])))
    anchors, nodes = np.array([0, 2]), np.array([168, 180])
    z = np.array([relative(truth[a], truth[i]) for a, i in zip(anchors, nodes)])
    cov = np.tile(np.diag([1e-4, 1e-4, np.deg2rad(0.1) ** 2]), (2, 1, 1))
    assert not consistent(anchors, nodes, z, cov, poses, strict).all()
    assert consistent(anchors, nodes, z, cov, poses, slipping).all()


def test_groups_of_edges_are_weighed_by_how_far_they_erred() -> None:
    rng = np.random.default_rng(2)
    n = 300
    poses = np.column_stack([np.arange(n) * 0.5, np.zeros(n), np.zeros(n)])
    g = PoseGraph(poses.copy())
    k = np.arange(n - 1)
    step = np.tile([0.5, 0.0, 0.0], (n - 1, 1))
    sd = np.array([0.01, 0.01, 0.002])
    info = np.tile(np.diag(sd**-2), (n - 1, 1, 1))  # claims 1 cm and 0.1 deg
    # the front end's steps err three times what they claim; the matches as they claim
    g.add_many(k, k + 1, step + rng.normal(0, 3 * sd, (n - 1, 3)), None, np.zeros(n - 1, bool), info)
    g.add_many(k, k + 1, step + rng.normal(0, sd, (n - 1, 3)), None, np.zeros(n - 1, bool), info, True)
    f = variance_factors(g, poses)
    assert f["front"] == pytest.approx(9.0, rel=0.3) and f["match"] == pytest.approx(1.0, rel=0.3)
    assert f["loop"] == 1.0  # (no loop)
    w = reweighted(g, f)
    assert w.info[0, 0, 0] == pytest.approx(1e4 / f["front"]) and w.info[-1, 0, 0] == pytest.approx(1e4 / f["match"])
    # (measured at the truth: the poses the edges are checked at)


def test_loops_that_share_one_look_alike_do_not_outvote_an_independent_one() -> None:
    """Five loops from one stretch of path into one submap, all slid 0.8 m alike (one look-alike
    the submap holds), and one true loop from elsewhere: counted one by one the five outvote it;
    as one group they are one piece of evidence, and the front end's path (which agrees with the
    true loop) decides."""
    poses = lap()
    p = paths(poses)
    anchors = np.array([10, 10, 10, 10, 10, 30])
    nodes = np.array([150, 151, 152, 153, 154, 170])
    submap = np.array([1, 1, 1, 1, 1, 3])
    z = np.array([relative(poses[a], poses[i]) for a, i in zip(anchors, nodes)])
    z[:5] = [compose(zz, [0.8, 0.0, 0.0]) for zz in z[:5]]
    cov = np.tile(np.diag([1e-4, 1e-4, np.deg2rad(0.1) ** 2]), (6, 1, 1))
    chi2 = gate(anchors, nodes, z, cov, poses, p)
    travel = p.travel[nodes]
    group = correlated(submap, travel, 2.0)
    assert len(set(group[:5].tolist())) == 1 and group[5] != group[0]
    assert consistent(anchors, nodes, z, cov, poses, p).tolist() == [True] * 5 + [False]  # by numbers
    keep = consistent(anchors, nodes, z, cov, poses, p, group=group, prior=chi2)
    assert keep.tolist() == [False] * 5 + [True]


def test_a_group_stands_as_one_loop_until_loops_into_another_submap_agree() -> None:
    poses = lap()
    p = paths(poses)
    anchors = np.array([10, 10, 10, 40])
    nodes = np.array([150, 151, 152, 160])
    submap = np.array([1, 1, 1, 4])
    z = np.array([relative(poses[a], poses[i]) for a, i in zip(anchors, nodes)])
    cov = np.tile(np.diag([1e-4, 1e-4, np.deg2rad(0.1) ** 2]), (4, 1, 1))
    group = correlated(submap, p.travel[nodes], 2.0)
    assert confirmed(anchors, nodes, submap, z, cov, poses, p, group).all()
    # the other submap's loop slid a metre: it confirms nothing, and nothing confirms it
    z[3] = compose(z[3], [1.0, 0.0, 0.0])
    assert not confirmed(anchors, nodes, submap, z, cov, poses, p, group).any()
    # and loops into the next submap (most of the same scans) never confirm each other
    near = np.array([1, 1, 1, 2])
    z[3] = relative(poses[40], poses[160])
    assert not confirmed(anchors, nodes, near, z, cov, poses, p, correlated(near, p.travel[nodes], 0.1)).any()


def test_the_chain_knows_the_path_where_scans_pinned_it_and_not_where_they_did_not() -> None:
    """Edges over 1, 4 and 16 nodes of a straight 100 m path: where they pin the path along it
    (a corridor with pillars) the covariance between its ends is centimetres, and a loop slid
    0.5 m along is refused by the gate, which per-metre drift let through; where the edges
    pin nothing along (a bare corridor), the same loop passes."""
    n = 201
    poses = np.column_stack([np.arange(n) * 0.5, np.zeros(n), np.zeros(n)])
    travel = poses[:, 0].copy()
    jitter = np.diag([0.005**2, 0.005**2, np.deg2rad(0.1) ** 2])
    missing = np.tile(np.diag([0.1**2, 0.1**2, np.deg2rad(4.0) ** 2]), (n, 1, 1))

    def chain(along_m: float) -> Chain:
        i, j = [], []
        for m in (1, 4, 16):
            i += list(range(n - m))
            j += list(range(m, n))
        ii, jj = np.array(i), np.array(j)
        info = np.tile(np.diag([along_m**-2, 0.003**-2, np.deg2rad(0.05) ** -2]), (len(ii), 1, 1))
        return Chain.of(poses, ii, jj, info, missing)

    a, i = np.array([0]), np.array([n - 1])
    slid = compose(relative(poses[0], poses[-1]), [0.5, 0.0, 0.0])[None]
    cov = np.diag([1e-4, 1e-4, np.deg2rad(0.1) ** 2])[None]
    drift = Paths(poses, travel, jitter, 0.02, np.deg2rad(0.05))
    pinned = Paths(poses, travel, jitter, 0.02, np.deg2rad(0.05), chain=chain(0.005))
    bare = Paths(poses, travel, jitter, 0.02, np.deg2rad(0.05), chain=chain(2.0))
    assert np.sqrt(pinned.between(a, i)[0, 0, 0]) < 0.05
    assert np.sqrt(bare.between(a, i)[0, 0, 0]) > 0.5
    assert gate(a, i, slid, cov, poses, drift)[0] < 16.27
    assert gate(a, i, slid, cov, poses, pinned)[0] > 16.27
    assert gate(a, i, slid, cov, poses, bare)[0] < 16.27
    # a step no edge spans is as unsure as a slip
    gap = Chain.of(poses, np.array([0, 2]), np.array([1, 3]), np.tile(np.eye(3) * 1e6, (2, 1, 1)), missing)
    assert gap.between(np.array([1]), np.array([2]))[0, 0, 0] == pytest.approx(0.1**2)
