import dataclasses

import cv2
import numpy as np
import pytest

from multithumbs.errors import InputError
from multithumbs.synth.scene import SceneConfig, synthesize
from multithumbs.viz.overlay import composite, render_people, render_world_frame, write_overlay_video


def iou(a: np.ndarray, b: np.ndarray) -> float:
    union = (a | b).sum()
    return float((a & b).sum() / union) if union else 1.0


@pytest.fixture(scope="module")
def crowd(body):
    """Three people, 320x180, two shots: enough pixels per person for a meaningful IoU."""
    return synthesize(SceneConfig(num_people=3, num_shots=2, num_frames=6, seed=11, image_size=(180, 320)), body)


def silhouette_ious(world, instance, body):
    per_person, per_frame = [], []
    for f in range(world.num_frames):
        ids, layer = render_world_frame(world, f, body)
        per_frame.append(iou(layer.person >= 0, instance[f] >= 0))
        for i, gid in enumerate(ids):
            if (instance[f] == gid).sum() >= 200:
                per_person.append(iou(layer.person == i, instance[f] == gid))
    return np.array(per_person), np.array(per_frame)


def test_meshes_land_on_the_people(crowd, body):
    per_person, per_frame = silhouette_ious(crowd.truth.world, crowd.instance, body)
    assert len(per_person) >= 10
    assert per_person.min() >= 0.7 and per_frame.min() >= 0.7
    assert np.median(per_person) > 0.95


def test_misplaced_meshes_miss(crowd, body):
    """The IoU check can fail: people shifted by 40 cm no longer cover their masks."""
    world = crowd.truth.world
    shifted = dataclasses.replace(world, transl=world.transl + np.array([0.4, 0.0, 0.0]))
    per_person, _ = silhouette_ious(shifted, crowd.instance, body)
    assert np.median(per_person) < 0.7


def test_render_people_shapes_and_anchors(crowd, body):
    world = crowd.truth.world
    vertices = crowd.vertices[:, 0]
    layer = render_people(vertices, body.faces, np.eye(3), world.K[0], world.R[0], world.t[0], world.image_size)
    assert layer.rgb.shape == (180, 320, 3) and layer.person.shape == (180, 320) and layer.anchors.shape == (3, 2)
    for i in range(3):
        rows = np.nonzero((layer.person == i).any(axis=1))[0]
        if rows.size:  # the label anchor is at the top of the person's silhouette
            assert abs(layer.anchors[i, 1] - rows.min()) < 3
    # Colour by mesh: pure red, green, blue meshes shaded by the headlight keep their hue.
    for i in range(3):
        hit = layer.person == i
        if hit.any():
            assert np.all(layer.rgb[hit].argmax(axis=1) == i)
    empty = render_people(np.zeros((0, 10, 3)), body.faces, np.zeros((0, 3)), world.K[0], world.R[0], world.t[0],
                          world.image_size)
    assert (empty.person == -1).all()
    frame = crowd.frames[0]
    assert np.array_equal(composite(frame, empty), frame)
    blended = composite(frame, layer, opacity=1.0)
    hit = layer.person >= 0
    np.testing.assert_allclose(blended[hit], np.round(255 * layer.rgb[hit]), atol=1)
    with pytest.raises(InputError, match="vertices"):
        render_people(np.zeros((5, 3)), body.faces, np.zeros((1, 3)), world.K[0], world.R[0], world.t[0], (10, 10))


def read_video(path):
    capture = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame)
    capture.release()
    return frames


def test_overlay_video_opens_with_opencv(small_scene, body, tmp_path):
    world = small_scene.world
    path = write_overlay_video(tmp_path / "overlay.mp4", world, small_scene.video_path, body)
    frames = read_video(path)
    h, w = world.image_size
    assert len(frames) == world.num_frames and frames[0].shape == (h, w, 3)
    seen = []
    side = write_overlay_video(tmp_path / "side.mp4", world, small_scene.video_path, body, truth=small_scene.truth,
                               progress=lambda done, total: seen.append((done, total)))
    frames = read_video(side)
    assert len(frames) == world.num_frames and frames[0].shape == (h, 2 * w, 3)
    assert seen[-1] == (world.num_frames, world.num_frames)
    # The first frame after the cut carries the red cut border; the frame before it does not.
    cut = int(world.cut_frames[0])
    red = lambda img: img[1:4, w // 2, 2].mean() > 150 and img[1:4, w // 2, 0].mean() < 120  # noqa: E731 (BGR)
    assert red(frames[cut]) and not red(frames[cut - 1])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["overlay.mp4", "side.mp4"]


def test_video_mismatch_errors(small_scene, body, tmp_path):
    world = small_scene.world
    longer = dataclasses.replace(world, **{k: np.concatenate([getattr(world, k)] * 2, axis=a)
                                           for k, a in (("global_orient", 1), ("body_pose", 1), ("transl", 1),
                                                        ("valid", 1), ("K", 0), ("R", 0), ("t", 0))},
                                 keypoints2d=None)
    with pytest.raises(InputError, match="has 12 frames but the result has 24"):
        write_overlay_video(tmp_path / "o.mp4", longer, small_scene.video_path, body)
    shorter = dataclasses.replace(world, **{k: getattr(world, k)[:, :8] for k in
                                            ("global_orient", "body_pose", "transl", "valid")},
                                  K=world.K[:8], R=world.R[:8], t=world.t[:8], keypoints2d=None)
    with pytest.raises(InputError, match="more frames than the result"):
        write_overlay_video(tmp_path / "o.mp4", shorter, small_scene.video_path, body)
    resized = dataclasses.replace(world, image_size=(60, 100))
    with pytest.raises(InputError, match="frames are 200x120"):
        write_overlay_video(tmp_path / "o.mp4", resized, small_scene.video_path, body)
    with pytest.raises(InputError, match="no such video"):
        write_overlay_video(tmp_path / "o.mp4", world, tmp_path / "missing.mp4", body)
    assert not list(tmp_path.iterdir())
