import numpy as np

from multithumbs.appearance import DESCRIPTOR_SIZE, REGION_SIZE
from multithumbs.method.reid import Candidates, ReidConfig, match_people, pose_dissimilarity


def _descriptor(hue_bin: int) -> np.ndarray:
    d = np.zeros(DESCRIPTOR_SIZE)
    for r in range(4):
        d[r * REGION_SIZE] = 1.0
        d[r * REGION_SIZE + 1 + hue_bin] = 1.0
    return d


def _people(roots, hues, rng):
    n = len(roots)
    return Candidates(np.asarray(roots, float), np.stack([_descriptor(h) for h in hues]) if n else np.zeros((0, DESCRIPTOR_SIZE)),
                      rng.normal(0, 0.3, (n, 23, 3)), np.ones((n, 23), bool))


def test_solves_a_permuted_assignment():
    rng = np.random.default_rng(0)
    before = _people([[0, 0, 0], [2, 0, 0], [0, 2, 0], [3, 3, 0]], [0, 6, 12, 18], rng)
    perm = np.array([2, 0, 3, 1])
    after = Candidates(before.root[perm] + rng.normal(0, 0.05, (4, 3)), before.appearance[perm],
                       before.body_pose[perm], before.joint_visible[perm])
    m = match_people(before, after)
    got = dict(map(tuple, m.pairs))
    assert got == {int(perm[j]): j for j in range(4)}
    assert m.cost.shape == (4, 4)


def test_rejects_a_far_pair_and_handles_empty_sides():
    rng = np.random.default_rng(1)
    before = _people([[0, 0, 0], [5, 0, 0]], [0, 6], rng)
    after = _people([[0.1, 0, 0], [5.0, 3.0, 0]], [0, 6], rng)  # the second moved 3 m: someone else
    m = match_people(before, after)
    assert m.pairs.tolist() == [[0, 0]]
    none = match_people(before, _people(np.zeros((0, 3)), [], rng))
    assert none.pairs.shape == (0, 2) and none.cost.shape == (2, 0)


def test_appearance_and_pose_break_a_distance_tie():
    rng = np.random.default_rng(2)
    before = _people([[0, 0, 0], [0.3, 0, 0]], [0, 12], rng)
    after = Candidates(np.array([[0.15, 0, 0], [0.15, 0, 0]]), before.appearance[::-1], before.body_pose[::-1],
                       before.joint_visible)
    assert match_people(before, after).pairs.tolist() == [[0, 1], [1, 0]]
    geo_only = match_people(before, after, ReidConfig(w_app=0, w_pose=0))
    assert len(geo_only.pairs) == 2  # a tie: any assignment, but both kept within tau


def test_pose_dissimilarity_counts_only_joints_visible_in_both():
    a = np.zeros((1, 23, 3))
    b = np.zeros((1, 23, 3))
    b[0, 5] = [0.5, 0, 0]
    vis_all = np.ones((1, 23), bool)
    vis_not5 = vis_all.copy()
    vis_not5[0, 5] = False
    np.testing.assert_allclose(pose_dissimilarity(a, b, vis_all, vis_all), [[0.5 / 23]])
    np.testing.assert_allclose(pose_dissimilarity(a, b, vis_all, vis_not5), [[0.0]])


def test_an_unknown_distance_neither_costs_nor_gates():
    # Across a cut whose cameras mean nothing (the space fell back, nobody seen on both sides), the roots
    # are placed in unrelated frames: D would match by where the cameras happen to be and reject real pairs.
    import dataclasses

    rng = np.random.default_rng(3)
    before = _people([[0, 0, 0], [1.0, 0, 0]], [0, 12], rng)
    # Each reappears near where the other was (the two sides' frames are unrelated): D swaps them.
    after = Candidates(np.array([[1.2, 0, 0], [0.0, 0, 0]]), before.appearance, before.body_pose,
                       before.joint_visible)
    assert match_people(before, after).pairs.tolist() == [[0, 1], [1, 0]]
    unknown = dataclasses.replace(before, distance_known=np.array([False, False]))
    assert match_people(unknown, after).pairs.tolist() == [[0, 0], [1, 1]]  # appearance and pose decide
    # The gate: someone 5 m from where they were is someone else only when the distance means something.
    one, far = _people([[0, 0, 0]], [0], rng), _people([[5.0, 0, 0]], [0], rng)
    assert match_people(one, far).pairs.shape == (0, 2)
    assert match_people(dataclasses.replace(one, distance_known=np.array([False])), far).pairs.tolist() == [[0, 0]]


def test_a_root_seen_before_is_carried_along_its_walk_hand_worked():
    # Last seen 0.5 s before the cut walking 1.2 m/s along x, first seen 0.25 s after it at x = 0.8:
    # carried 0.75 s it stands at x = 0.9, so D = 0.1 (the paper's D from where it was seen: 0.8).
    import dataclasses

    from multithumbs.method.reid import distance_gate, fused_cost

    rng = np.random.default_rng(4)
    walker = dataclasses.replace(_people([[0, 0, 0]], [0], rng), gap=np.array([0.5]),
                                 velocity=np.array([[1.2, 0, 0]]))
    later = dataclasses.replace(_people([[0.8, 0, 0]], [0], rng), gap=np.array([0.25]))
    config = ReidConfig(w_app=0.0, w_pose=0.0)
    np.testing.assert_allclose(distance_gate(np.array([[0.75]]), config), [[1 + 1.5 * 0.75]])
    cost, distance, *_ = fused_cost(walker, later, config)
    np.testing.assert_allclose(distance, [[0.1]], atol=1e-12)
    np.testing.assert_allclose(cost, [[0.1]], atol=1e-12)
    standing = ReidConfig(w_app=0.0, w_pose=0.0, motion_window=0.0)
    np.testing.assert_allclose(fused_cost(walker, later, standing)[1], [[0.8]])
    # Carried no longer than the window the velocity was fit on (1 s): 3 s apart, it stands at x = 1.2.
    far_later = dataclasses.replace(later, gap=np.array([2.5]))
    np.testing.assert_allclose(fused_cost(walker, far_later, config)[1], [[0.4]])
    # Both seen at the cut: nothing is carried, the paper's D.
    at_cut = dataclasses.replace(walker, gap=np.array([0.0]))
    np.testing.assert_allclose(fused_cost(at_cut, dataclasses.replace(later, gap=np.array([0.0])), config)[1],
                               [[0.8]])


def test_a_person_who_walked_on_is_told_from_one_standing_where_they_vanished():
    # s04's cut in miniature (docs/RESULTS.md, session 25). Two walk away from the camera; the second is lost
    # 0.9 s before the cut at z = 2.7. After the cut someone new stands at z = 2.85 and the second, walking
    # on at 1 m/s, is seen at z = 3.6. From where it was last seen D gives it to the newcomer; carried along
    # its walk it finds itself.
    import dataclasses

    rng = np.random.default_rng(5)
    pose = rng.normal(0, 0.3, (1, 23, 3)).repeat(3, 0)
    looks = np.stack([_descriptor(0), _descriptor(6), _descriptor(12)])
    before = Candidates(np.array([[0.0, 0, 2.0], [0.6, 0, 2.7]]), looks[:2], pose[:2], np.ones((2, 23), bool),
                        gap=np.array([0.0, 0.9]), velocity=np.array([[0, 0, 0.2], [0, 0, 1.0]]))
    after = Candidates(np.array([[0.0, 0, 2.05], [0.7, 0, 3.6], [0.7, 0, 2.85]]), looks, pose,
                       np.ones((3, 23), bool), gap=np.zeros(3))
    assert match_people(before, after).pairs.tolist() == [[0, 0], [1, 1]]
    standing = dataclasses.replace(before, velocity=None)
    assert match_people(standing, after).pairs.tolist() == [[0, 0], [1, 2]]
