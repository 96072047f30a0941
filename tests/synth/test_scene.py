import dataclasses

import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.synth.scene import SceneConfig, build_scene, config_from_json, synthesize
from multithumbs.synth.suite import suite, suite_scene

SMALL = SceneConfig(num_people=2, num_shots=2, num_frames=6, seed=5, image_size=(180, 320), cut_angle_deg=40)


@pytest.fixture(scope="module")
def video(body):
    return synthesize(SMALL, body)


def test_renders_are_reproducible_from_the_seed(body, video):
    again = synthesize(SMALL, body)
    np.testing.assert_array_equal(again.frames, video.frames)
    np.testing.assert_array_equal(again.instance, video.instance)
    other = build_scene(dataclasses.replace(SMALL, seed=6))
    assert not np.allclose(other.motions[0].position, video.scene.motions[0].position)


def test_ground_truth_shapes_and_splice(video):
    truth = video.truth
    world = truth.world
    assert world.global_orient.shape == (2, 6, 3) and world.keypoints2d.shape == (2, 6, 24, 3)
    assert world.cut_frames.tolist() == video.scene.cut_frames.tolist() and len(world.cut_frames) == 1
    cut = int(world.cut_frames[0])
    assert set(truth.camera_ids[:cut]) == {0} and set(truth.camera_ids[cut:]) == {1}
    np.testing.assert_allclose(world.R[cut], video.scene.cameras.R[1, cut])
    # the two shots' cameras differ by the cut angle (yaw about the scene centre)
    c0, c1 = (-(world.R[f].T @ world.t[f]) for f in (cut - 1, cut))
    angle = np.degrees(np.arccos(np.dot(c0[:2], c1[:2]) / np.linalg.norm(c0[:2]) / np.linalg.norm(c1[:2])))
    assert abs(angle - 40) < 1.0


def test_projected_ground_truth_joints_land_on_the_rendered_body(video):
    kp = video.truth.world.keypoints2d
    hits = total = 0
    for p in range(2):
        for f in range(6):
            if not video.truth.visible[p, f]:
                continue
            for j in (0, 3, 6, 9, 12):  # torso joints lie inside the body's silhouette
                u, v, conf = kp[p, f, j]
                if conf < 0.5:
                    continue
                total += 1
                hits += video.instance[f, int(round(v)), int(round(u))] == p
    assert total >= 10 and hits / total >= 0.9


def test_feet_touch_the_floor_and_people_are_upright(video):
    verts = video.vertices
    np.testing.assert_allclose(verts[..., 2].min(axis=2), 0.0, atol=1e-4)
    height = verts[..., 2].max(axis=2)
    assert np.all((height > 1.4) & (height < 2.0))


def test_bad_configs_are_rejected_with_a_named_input():
    with pytest.raises(InputError, match="people"):
        SceneConfig(num_people=0)
    with pytest.raises(InputError, match="frames"):
        SceneConfig(num_shots=5, num_frames=6)
    with pytest.raises(InputError, match="cut-angle"):
        SceneConfig(cut_angle_deg=200)


def test_config_survives_json(video):
    assert config_from_json(video.truth.metadata["config"]) == SMALL


def test_standard_suite_covers_what_it_promises():
    scenes = suite("standard")
    assert len(scenes) >= 12 and len({c.name for c in scenes}) == len(scenes)
    assert {c.num_people for c in scenes} >= {2, 3, 4} and {c.num_shots for c in scenes} >= {2, 3}
    angles = [c.cut_angle_deg for c in scenes]
    assert min(angles) <= 20 and max(angles) >= 90
    assert any(c.moving_cameras for c in scenes) and any(not c.moving_cameras for c in scenes)
    assert any(c.only_in_one_shot for c in scenes)
    assert any(c.dressed_alike for c in scenes) and any(c.crossing_pair for c in scenes)
    assert any(c.dressed_alike and c.abreast_pair for c in scenes)
    with pytest.raises(InputError, match="not in suite"):
        suite_scene("standard", "nope")


def _facing_away(motion, frame, camera_xy):
    """Cosine between a person's heading and the direction from the camera to them (1: back to the camera)."""
    to_person = motion.position[frame] - camera_xy
    heading = np.array([np.cos(motion.heading[frame]), np.sin(motion.heading[frame])])
    return float(heading @ to_person / np.linalg.norm(to_person))


@pytest.mark.parametrize("name", ["s08_dressed_alike", "s12_alike_crossing_25deg"])
def test_dressed_alike_pair_walks_abreast_through_the_cut(name):
    config = suite_scene("standard", name)
    assert config.abreast_pair is not None and set(config.abreast_pair) == set(config.dressed_alike[0])
    scene = build_scene(config)
    a, b = (scene.motions[p] for p in config.abreast_pair)
    cut = int(scene.cut_frames[0])
    # The same heading throughout, 1-1.5 m apart side by side, both walking through the cut.
    heading_gap = np.degrees(np.abs(np.angle(np.exp(1j * (a.heading - b.heading)))))
    assert heading_gap.max() < 3.0
    distance = np.linalg.norm(a.position - b.position, axis=1)
    assert np.all((distance >= 1.0) & (distance <= 1.5))
    for m in (a, b):
        assert m.gait_amount[cut - 1] == 1.0 and m.gait_amount[cut] == 1.0
        assert np.linalg.norm(m.position[cut] - m.position[cut - 1]) > 0.02
    # The same view at the cut: each boundary frame's camera sees both from the same side (here their
    # backs), within the perspective difference of two people 1.2 m apart.
    for shot, frame in ((0, cut - 1), (1, cut)):
        centre = -(scene.cameras.R[shot, frame].T @ scene.cameras.t[shot, frame])[:2]
        views = [_facing_away(m, frame, centre) for m in (a, b)]
        assert min(views) > 0.5
        assert np.degrees(abs(np.arccos(views[0]) - np.arccos(views[1]))) < 25.0
    # Nobody walks into them: everyone else keeps 0.55 m at least (a crossing partner passes at 0.6 m).
    for p, other in enumerate(scene.motions):
        if p not in config.abreast_pair:
            for m in (a, b):
                assert np.linalg.norm(other.position - m.position, axis=1).min() > 0.55


def test_abreast_pair_is_seen_in_both_boundary_frames(body):
    config = SceneConfig(num_people=3, num_shots=2, num_frames=12, seed=8, image_size=(180, 320), cut_angle_deg=30,
                         dressed_alike=((0, 1),), abreast_pair=(0, 1))
    video = synthesize(config, body)
    cut = int(video.scene.cut_frames[0])
    for frame in (cut - 1, cut):
        for p in (0, 1):
            assert (video.instance[frame] == p).sum() > 400  # each of the pair in full view, not hidden
    np.testing.assert_array_equal(video.scene.clothing[0].top, video.scene.clothing[1].top)
    assert config_from_json(video.truth.metadata["config"]) == config
    # reproducible from the seed
    again = build_scene(config)
    for m, n in zip(again.motions, video.scene.motions):
        np.testing.assert_array_equal(m.position, n.position)


def test_abreast_pair_options_are_checked():
    with pytest.raises(InputError, match="two different persons"):
        SceneConfig(abreast_pair=(1, 1))
    with pytest.raises(InputError, match="out of range"):
        SceneConfig(num_people=2, abreast_pair=(0, 2))
    with pytest.raises(InputError, match="crossing pair"):
        SceneConfig(abreast_pair=(0, 1), crossing_pair=(1, 0))
    with pytest.raises(InputError, match="abreast_spacing"):
        SceneConfig(abreast_pair=(0, 1), abreast_spacing=0.2)
