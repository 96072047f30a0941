import numpy as np
import pycolmap
import pytest

from multithumbs.errors import InputError
from multithumbs.export.cameras import (
    camera_arrays, check_scene_points, colmap_text, frame_image_name, project_to_frame, write_cameras_npz,
    write_colmap_text,
)


def scene_points(world, n=40, seed=0):
    rng = np.random.default_rng(seed)
    return [rng.uniform([-2.0, -2.0, 0.0], [2.0, 2.0, 2.0], (n, 3)) for _ in world.cut_frames]


def test_cameras_npz(small_scene, tmp_path):
    world = small_scene.world
    path = write_cameras_npz(tmp_path / "cameras.npz", world, np.array([0, 0, 1.0]))
    with np.load(path, allow_pickle=False) as data:
        np.testing.assert_allclose(data["K"], world.K)
        np.testing.assert_allclose(data["R"], world.R)
        np.testing.assert_allclose(data["t"], world.t)
        to_world = data["camera_to_world"]
        # camera_to_world inverts the extrinsics: it maps the camera centre's origin to the centre.
        np.testing.assert_allclose(to_world[:, :3, 3], data["centres"])
        np.testing.assert_allclose(to_world[:, :3, :3] @ world.R, np.tile(np.eye(3), (world.num_frames, 1, 1)),
                                   atol=1e-12)
        np.testing.assert_array_equal(data["image_size"], world.image_size)
        np.testing.assert_array_equal(data["shot"], (np.arange(world.num_frames) >= world.cut_frames[0]).astype(int))
    assert "world_up" not in camera_arrays(world)


def test_colmap_reads_back(small_scene, tmp_path):
    world = small_scene.world
    points = scene_points(world)
    files = write_colmap_text(tmp_path / "colmap", world, points)
    assert sorted(p.name for p in files.values()) == ["cameras.txt", "images.txt", "points3D.txt"]
    rec = pycolmap.Reconstruction(str(tmp_path / "colmap"))
    assert rec.num_images() == world.num_frames and rec.num_points3D() == len(points[0])
    (camera,) = rec.cameras.values()
    K = world.K[0]
    np.testing.assert_allclose(camera.params, [K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5], atol=1e-6)
    assert (camera.width, camera.height) == (world.image_size[1], world.image_size[0])
    for image in rec.images.values():
        f = image.image_id - 1
        assert image.name == frame_image_name(f)
        pose = image.cam_from_world()
        np.testing.assert_allclose(pose.rotation.matrix(), world.R[f], atol=1e-9)
        np.testing.assert_allclose(pose.translation, world.t[f], atol=1e-9)
    # Observations sit where the points project (COLMAP pixel centres at +0.5): zero reprojection error.
    cut = int(world.cut_frames[0])
    image = rec.images[cut + 1]
    observed = [p for p in image.points2D if p.has_point3D()]
    uv, inside = project_to_frame(world, cut, points[0])
    assert len(observed) == int(inside.sum()) > 0
    for p2d in observed:
        np.testing.assert_allclose(p2d.xy, uv[p2d.point3D_id - 1] + 0.5, atol=1e-4)
    assert rec.compute_mean_reprojection_error() < 1e-3


def test_colmap_without_points_and_with_colours(small_scene):
    world = small_scene.world
    text = colmap_text(world)
    assert "# Number of points: 0" in text["points3D.txt"]
    colours = [np.tile([[10, 20, 30]], (40, 1))]
    text = colmap_text(world, scene_points(world), colours)
    assert " 10 20 30 0" in text["points3D.txt"].splitlines()[3]


def test_bad_scene_points(small_scene):
    world = small_scene.world
    with pytest.raises(InputError, match="one array per cut"):
        check_scene_points([np.zeros((3, 3))] * 2, 1)
    with pytest.raises(InputError, match=r"scene_points\[0\]: expected shape"):
        check_scene_points([np.zeros((3, 2))], 1)
    with pytest.raises(InputError, match="non-finite"):
        check_scene_points([np.full((3, 3), np.nan)], 1)
    with pytest.raises(InputError, match="point_colors"):
        colmap_text(world, scene_points(world), [np.zeros((3, 3))])
