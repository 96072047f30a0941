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
    with pytest.raises(InputError, match="not in suite"):
        suite_scene("standard", "nope")
