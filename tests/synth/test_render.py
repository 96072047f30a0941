import dataclasses

import cv2
import numpy as np
import pytest
import trimesh

from multithumbs.errors import InputError
from multithumbs.geometry import intrinsics_from_fov, look_at, project_points, unproject
from multithumbs.synth.render import MeshInstance, cast_room, rasterize, ray_box_entry, render_view
from multithumbs.synth.room import NUM_ROOM_SURFACES, Box, Room, make_room, room_surfaces

SIZE = (360, 640)
K = intrinsics_from_fov(SIZE[1], SIZE[0], 70.0)


@pytest.fixture(scope="module")
def room() -> Room:
    return make_room(0)


def empty_room() -> Room:
    return Room(8.0, 7.0, 3.0, (), seed=0)


def sphere(centre, radius=0.4, colour=(0.8, 0.3, 0.2), subdivisions=4) -> MeshInstance:
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    vertices = np.asarray(mesh.vertices) + np.asarray(centre, float)
    return MeshInstance(vertices, np.asarray(mesh.faces), np.tile(colour, (len(vertices), 1)))


def orbit_camera(azimuth_deg: float, radius: float = 3.0, height: float = 1.6, target=(0.0, 0.0, 1.0)):
    a = np.deg2rad(azimuth_deg)
    return look_at(np.array([radius * np.cos(a), radius * np.sin(a), height]), np.array(target))


def pixel_grid(size):
    v, u = np.mgrid[:size[0], :size[1]]
    return np.stack([u, v], axis=-1).reshape(-1, 2).astype(float)


ROOM_VIEWS = [(azimuth, 1.6, (0, 0, 1)) for azimuth in range(0, 360, 45)] + [
    (30, 2.5, (3, 3, 0.3)), (120, 0.5, (-4, 3.5, 2.8)), (270, 1.7, (0, -3.5, 1.0))]


def test_room_depth_lies_on_the_hit_surface(room):
    size = (180, 320)
    k = intrinsics_from_fov(size[1], size[0], 70.0)
    surfaces = room_surfaces(room)
    seen = set()
    for azimuth, height, target in ROOM_VIEWS:
        R, t = orbit_camera(azimuth, height=height, target=target)
        depth, surface, _ = cast_room(room, k, R, t, size)
        cam = unproject(pixel_grid(size), depth.reshape(-1), k)
        world = (cam - t) @ R  # x = R^T (x_cam - t)
        sid = surface.reshape(-1)
        seen |= set(sid.tolist())
        origin = np.array([s.origin for s in surfaces])[sid]
        normal = np.array([s.normal for s in surfaces])[sid]
        u_axis, v_axis = np.array([s.u_axis for s in surfaces])[sid], np.array([s.v_axis for s in surfaces])[sid]
        extent = np.array([s.extent for s in surfaces])[sid]
        rel = world - origin
        # On the plane of the surface it says it hit, and within that rectangle.
        assert np.abs((rel * normal).sum(-1)).max() < 1e-4
        along_u, along_v = (rel * u_axis).sum(-1), (rel * v_axis).sum(-1)
        assert np.all(along_u > -1e-4) and np.all(along_u < extent[:, 0] + 1e-4)
        assert np.all(along_v > -1e-4) and np.all(along_v < extent[:, 1] + 1e-4)
        # And nothing is in front of it: the point is not inside a box nor outside the room.
        assert np.all(room.is_free(world, margin=-1e-4))
    assert set(range(NUM_ROOM_SURFACES)) <= seen  # floor, ceiling and all four walls
    seen_boxes = {(s - NUM_ROOM_SURFACES) // 6 for s in seen if s >= NUM_ROOM_SURFACES}
    assert len(seen_boxes) >= len(room.boxes) - 1


def test_sphere_silhouette_is_its_projected_hull():
    R, t = look_at(np.array([0.0, -2.5, 1.2]), np.array([0.2, 0.0, 1.1]))
    mesh = sphere((0.0, 0.0, 1.2), radius=0.5)
    render = render_view(empty_room(), [mesh], K, R, t, SIZE)
    hull = cv2.convexHull(project_points(mesh.vertices, K, R, t).astype(np.float32))
    expected = np.zeros(SIZE, np.uint8)
    cv2.fillPoly(expected, [np.round(hull * 256).astype(np.int32)], 1, shift=8)
    mask = render.instance == 0
    iou = (mask & (expected > 0)).sum() / (mask | (expected > 0)).sum()
    assert mask.sum() > 5000 and iou > 0.97
    assert set(np.unique(render.instance).tolist()) == {-1, 0}


def test_sphere_depth_at_centre_pixel_is_analytic():
    centre, radius = np.array([0.3, 0.5, 1.3]), 0.4
    eye = np.array([0.0, -2.5, 1.5])
    R, t = look_at(eye, np.array([0.0, 0.0, 1.2]))
    render = render_view(empty_room(), [sphere(centre, radius)], K, R, t, SIZE)
    u, v = np.round(project_points(centre[None], K, R, t)[0]).astype(int)
    # Ray through the pixel centre with camera-z = 1, against the true sphere.
    d = R.T @ np.linalg.inv(K) @ np.array([u, v, 1.0])
    oc = eye - centre
    a, b, c = d @ d, 2 * d @ oc, oc @ oc - radius ** 2
    expected = (-b - np.sqrt(b * b - 4 * a * c)) / (2 * a)
    assert render.instance[v, u] == 0
    assert render.depth[v, u] == pytest.approx(expected, abs=1e-3)


def test_tilted_box_depth_is_perspective_correct_everywhere():
    # A box turned 35 degrees about z: every covered pixel's depth equals the exact ray-box entry.
    angle = np.deg2rad(35)
    rot = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    centre = np.array([0.2, 0.3, 1.0])
    box = trimesh.creation.box(extents=(0.8, 0.5, 1.2))
    vertices = np.asarray(box.vertices) @ rot.T + centre
    mesh = MeshInstance(vertices, np.asarray(box.faces), np.full((len(vertices), 3), 0.5))
    eye = np.array([-0.5, -2.8, 1.9])
    R, t = look_at(eye, np.array([0.2, 0.3, 0.9]))
    render = render_view(empty_room(), [mesh], K, R, t, SIZE)
    dirs = (np.c_[pixel_grid(SIZE), np.ones(SIZE[0] * SIZE[1])] @ np.linalg.inv(K).T) @ R  # camera z = 1
    param, _ = ray_box_entry(rot.T @ (eye - centre), dirs @ rot, np.array([-0.4, -0.25, -0.6]),
                             np.array([0.4, 0.25, 0.6]))
    analytic = param.reshape(SIZE)
    mask = render.instance == 0
    hit = np.isfinite(analytic)
    assert (mask & hit).sum() / (mask | hit).sum() > 0.99
    both = mask & hit
    np.testing.assert_allclose(render.depth[both], analytic[both], atol=1e-6)


def test_nearer_meshes_occlude_farther_ones():
    R, t = look_at(np.array([0.0, -3.0, 1.3]), np.array([0.0, 0.0, 1.2]))
    near, far = sphere((-0.15, -1.0, 1.2), 0.35, (0.2, 0.3, 0.9)), sphere((0.25, 0.5, 1.3), 0.5)
    alone = [render_view(empty_room(), [m], K, R, t, SIZE) for m in (near, far)]
    both = render_view(empty_room(), [far, near], K, R, t, SIZE)
    near_mask, far_mask = alone[0].instance == 0, alone[1].instance == 0
    assert (near_mask & far_mask).sum() > 1000  # they do overlap in the image
    np.testing.assert_array_equal(both.instance, np.where(near_mask, 1, np.where(far_mask, 0, -1)))
    np.testing.assert_array_equal(both.depth, np.minimum(alone[0].depth, alone[1].depth))
    np.testing.assert_array_equal(both.rgb[near_mask], alone[0].rgb[near_mask])


def test_mesh_behind_a_room_box_is_hidden():
    cabinet = Box((0.0, 0.0, 0.9), (1.5, 0.4, 1.8), "cabinet")
    walled, open_room = Room(8.0, 7.0, 3.0, (cabinet,), seed=0), Room(8.0, 7.0, 3.0, (), seed=0)
    R, t = look_at(np.array([0.0, -3.0, 1.2]), np.array([0.0, 0.0, 1.0]))
    ball = sphere((0.0, 1.0, 1.0), 0.3)
    assert (render_view(open_room, [ball], K, R, t, SIZE).instance == 0).sum() > 500
    hidden = render_view(walled, [ball], K, R, t, SIZE)
    assert np.all(hidden.instance == -1)


def test_faces_behind_the_near_plane_are_dropped():
    tri = np.array([[0.0, 0.0, 2.0], [0.1, 0.0, 2.0], [0.0, 0.1, -1.0]])
    frags = rasterize(tri, np.array([[0, 1, 2]]), K, SIZE)
    assert np.all(frags.face == -1) and np.all(np.isinf(frags.depth))
    frags = rasterize(tri * [1, 1, -1] + [0, 0, 3], np.array([[0, 1, 2]]), K, SIZE)
    assert np.any(frags.face == 0)


def test_render_is_reproducible_and_textures_follow_the_seed(room):
    R, t = orbit_camera(200)
    meshes = [sphere((0.3, 0.2, 1.0), 0.4)]
    a, b = (render_view(room, meshes, K, R, t, SIZE) for _ in range(2))
    for field in ("rgb", "depth", "instance"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert a.rgb.dtype == np.uint8 and a.depth.dtype == np.float32 and a.instance.dtype == np.int16
    reseeded = render_view(dataclasses.replace(room, seed=room.seed + 1), meshes, K, R, t, SIZE)
    np.testing.assert_array_equal(reseeded.depth, a.depth)  # same geometry...
    room_px = a.instance == -1
    assert np.abs(reseeded.rgb[room_px].astype(int) - a.rgb[room_px].astype(int)).mean() > 10  # ...new textures


def test_sensor_noise_is_optional_and_seeded(room):
    R, t = orbit_camera(200)
    clean = render_view(room, [], K, R, t, SIZE)
    noisy = [render_view(room, [], K, R, t, SIZE, noise_std=0.02, noise_seed=s) for s in (1, 1, 2)]
    np.testing.assert_array_equal(noisy[0].rgb, noisy[1].rgb)
    assert not np.array_equal(noisy[0].rgb, noisy[2].rgb)
    assert 2.0 < np.abs(noisy[0].rgb.astype(int) - clean.rgb.astype(int)).mean() < 8.0
    np.testing.assert_array_equal(noisy[0].depth, clean.depth)


def test_invalid_inputs_raise_input_error(room):
    R, t = orbit_camera(200)
    with pytest.raises(InputError, match="outside the room"):
        render_view(room, [], K, *look_at(np.array([0.0, -5.0, 1.5]), np.zeros(3)), SIZE)
    with pytest.raises(InputError, match="K"):
        render_view(room, [], K[:2], R, t, SIZE)
    with pytest.raises(InputError, match="rotation"):
        render_view(room, [], K, 2 * R, t, SIZE)
    with pytest.raises(InputError, match="faces"):
        MeshInstance(np.zeros((3, 3)), np.array([[0, 1, 3]]), np.zeros((3, 3)))
    with pytest.raises(InputError, match="vertex_colors"):
        MeshInstance(np.zeros((3, 3)), np.array([[0, 1, 2]]), np.full((3, 3), 2.0))


def _free_orbit_pair(room: Room, separation: float = 30.0):
    """Two cameras on a circle around the room centre, ``separation`` degrees apart, clear of boxes."""
    for azimuth in range(0, 360, 15):
        poses = [orbit_camera(azimuth + k * separation, radius=2.8) for k in (0, 1)]
        centres = np.array([-R.T @ t for R, t in poses])
        if np.all(room.is_free(centres, margin=0.4)):
            return poses
    raise AssertionError("no free camera pair")


@pytest.mark.parametrize("seed", [0, 2, 4])  # 2 and 4 have the fewest matches of seeds 0-5
def test_room_texture_supports_sift_matching(seed):
    room = make_room(seed)
    poses = _free_orbit_pair(room)
    grey = [cv2.cvtColor(render_view(room, [], K, R, t, SIZE).rgb, cv2.COLOR_RGB2GRAY) for R, t in poses]
    sift = cv2.SIFT_create()
    (kp1, des1), (kp2, des2) = (sift.detectAndCompute(g, None) for g in grey)
    assert min(len(kp1), len(kp2)) >= 500
    pairs = cv2.BFMatcher(cv2.NORM_L2).knnMatch(des1, des2, k=2)
    good = [m for m, n in pairs if m.distance < 0.75 * n.distance]
    pts1 = np.float32([kp1[m.queryIdx].pt for m in good])
    pts2 = np.float32([kp2[m.trainIdx].pt for m in good])
    _, inliers = cv2.findEssentialMat(pts1, pts2, K, method=cv2.RANSAC, prob=0.999, threshold=1.0)
    assert inliers.sum() >= 100
