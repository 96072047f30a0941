"""Result colours beside the truth: a relabelling of ids looks right, a real identity switch at a cut does not."""

import dataclasses

import numpy as np
import pytest

from multithumbs.export.posed import posed_joints
from multithumbs.metrics.alignment import Correspondence
from multithumbs.viz.overlay import overlay_image, render_world_frame
from multithumbs.viz.pairing import LEGEND, colouring_for, truth_colouring, unused_colors
from multithumbs.viz.palette import id_color
from multithumbs.viz.plots import trajectory_figure
from tests.export.conftest import rigid_copy, tilted_rotation

PER_PERSON = ("global_orient", "body_pose", "betas", "transl", "valid")


def permuted(world, order):
    """The same people and ids, but row ``i`` of the result is truth person ``order[i]``."""
    return dataclasses.replace(world, **{k: getattr(world, k)[list(order)] for k in PER_PERSON}, keypoints2d=None)


def switched_at_cut(world):
    """Result ids 0 and 1 exchange the people they follow at the first cut: a real identity switch."""
    cut = int(world.cut_frames[0])
    fields = {}
    for k in ("global_orient", "body_pose", "transl", "valid"):
        a = getattr(world, k).copy()
        a[:, cut:] = a[::-1, cut:]
        fields[k] = a
    # Same body shape for both, so the switch is a pure change of who is followed.
    fields["betas"] = np.repeat(world.betas.mean(axis=0, keepdims=True), world.num_people, axis=0)
    return dataclasses.replace(world, **fields, keypoints2d=None)


def panels(result, truth, body, frame):
    """Result and truth layers of one frame, the result coloured as the overlay video colours it."""
    colouring = colouring_for(result, posed_joints(result, body), truth, posed_joints(truth.world, body))
    blank = np.zeros((*truth.world.image_size, 3), np.uint8)
    _, _, result_layer = overlay_image(blank, result, frame, body, "result", colouring=colouring)
    true_ids, true_layer = render_world_frame(truth.world, frame, body)
    return result_layer, true_layer, true_ids


def colour_on(result_layer, true_layer, true_ids, gid):
    """The result's (unshaded) colour over true person ``gid``'s pixels, or None if too few of them."""
    hit = (true_layer.person == list(true_ids).index(gid)) & (result_layer.person >= 0) \
        if gid in list(true_ids) else np.zeros(true_layer.person.shape, bool)
    if hit.sum() < 50:
        return None
    rgb = result_layer.rgb[hit]
    chroma = (rgb / np.maximum(rgb.sum(-1, keepdims=True), 1e-6)).mean(axis=0)
    palette = {g: id_color(g) / id_color(g).sum() for g in range(10)}
    return min(palette, key=lambda g: np.linalg.norm(palette[g] - chroma))


def test_permuted_ids_look_like_the_truth(small_scene, body):
    """Ids 0/1 swapped over the whole video, in another world frame: both panels show the same colours."""
    truth = small_scene.truth
    result = rigid_copy(permuted(truth.world, [1, 0]), body, tilted_rotation(), np.array([1.0, 0.5, -2.0]))
    for frame in range(truth.world.num_frames):
        result_layer, true_layer, _ = panels(result, truth, body, frame)
        both = (result_layer.person >= 0) & (true_layer.person >= 0)
        assert both.sum() > 100
        np.testing.assert_allclose(result_layer.rgb[both], true_layer.rgb[both], atol=0.02)


def test_identity_switch_at_the_cut_changes_colour(small_scene, body):
    truth = small_scene.truth
    cut = int(truth.world.cut_frames[0])
    result = switched_at_cut(truth.world)
    before, after = panels(result, truth, body, cut - 1), panels(result, truth, body, cut)
    changed = 0
    for gid in truth.world.person_ids:
        a, b = colour_on(*before, int(gid)), colour_on(*after, int(gid))
        if a is not None and b is not None:
            assert a != b, f"truth #{gid}: the result kept colour {a} across the switch"
            changed += 1
    assert changed >= 1
    # While the permutation of the test above never changes colour on anyone.
    result = permuted(truth.world, [1, 0])
    before, after = panels(result, truth, body, cut - 1), panels(result, truth, body, cut)
    for gid in truth.world.person_ids:
        a, b = colour_on(*before, int(gid)), colour_on(*after, int(gid))
        assert a is None or b is None or a == b == int(gid)


def test_unpaired_people_get_unused_colours(small_scene):
    world = small_scene.world
    three = dataclasses.replace(world, person_ids=np.array([0, 5, 9]),
                                **{k: np.concatenate([getattr(world, k), getattr(world, k)[:1]]) for k in PER_PERSON},
                                keypoints2d=None, id_map=np.zeros((0, 3), int))
    truth = dataclasses.replace(small_scene.truth, world=dataclasses.replace(world, person_ids=np.array([4, 1])))
    pairing = Correspondence(np.array([2, -1]), np.zeros((2, 3)), np.ones((2, 3), int),
                             truth.visible, truth.visible)
    colouring = truth_colouring(three, truth, pairing)
    assert colouring.partner.tolist() == [-1, -1, 4] and colouring.legend == LEGEND
    np.testing.assert_allclose(colouring.colors[2], id_color(4))
    truth_colours = [id_color(4), id_color(1)]
    for row in (0, 1):
        assert all(np.abs(colouring.colors[row] - c).max() > 0.05 for c in truth_colours)
    assert np.abs(colouring.colors[0] - colouring.colors[1]).max() > 0.05
    assert unused_colors(3, [0, 2]).shape == (3, 3)
    np.testing.assert_allclose(unused_colors(2, [0, 2]), [id_color(1), id_color(3)])


def test_trajectory_plot_colours_by_the_pairing(small_scene, body):
    truth = small_scene.truth
    result = permuted(truth.world, [1, 0])
    joints = posed_joints(result, body)
    fig = trajectory_figure(result, joints, truth, posed_joints(truth.world, body))
    try:
        ax = fig.axes[0]
        assert LEGEND in ax.get_title()
        labels = {line.get_label(): line for line in ax.get_lines() if line.get_label().startswith("result #")}
        assert set(labels) == {"result #0 (paired: truth #1)", "result #1 (paired: truth #0)"}
        np.testing.assert_allclose(labels["result #0 (paired: truth #1)"].get_color(), id_color(1))
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)
