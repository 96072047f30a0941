import dataclasses

import numpy as np
import pytest
import rerun.chunk as rc

from multithumbs.errors import InputError
from multithumbs.export.posed import camera_centres, posed_people
from multithumbs.export.rrd import write_rrd
from multithumbs.video import iter_frames


def column(chunks, entity, component):
    """``{frame: value}`` of one component of one entity, read back with rerun's own RRD reader."""
    out = {}
    for chunk in chunks:
        if chunk.entity_path != entity:
            continue
        batch = chunk.to_record_batch()
        names = [n for n in batch.schema.names if n.endswith(component)]
        if not names:
            continue
        frames = batch.column("frame").to_pylist() if "frame" in batch.schema.names else [None] * batch.num_rows
        for f, value in zip(frames, batch.column(names[0]).to_pylist()):
            out[f] = value
    return out


@pytest.fixture(scope="module")
def recording(small_scene, body, tmp_path_factory):
    world = small_scene.world
    valid = world.valid.copy()
    valid[0, 3:5] = False
    world = dataclasses.replace(world, valid=valid)
    vertices, joints = posed_people(world, body)
    points = [np.random.default_rng(1).uniform(-1, 1, (30, 3))]
    path = write_rrd(tmp_path_factory.mktemp("rrd") / "scene.rrd", world, vertices, joints, body.faces, np.eye(3),
                     points, iter_frames(small_scene.video_path))
    return path, world, vertices, joints


def test_rerun_reads_the_recording(recording):
    path, world, vertices, joints = recording
    reader = rc.RrdReader(str(path))
    (entry,) = reader.recordings()
    entities = set(reader.store().schema().entity_paths())
    assert {"/world", "/world/camera", "/world/camera/image", "/world/people/0", "/world/people/1",
            "/world/people/0/joints", "/world/scene_points/cut_0", "/world/trajectories/0", "/cuts"} <= entities
    chunks = reader.stream().to_chunks()
    positions = column(chunks, "/world/people/1", "vertex_positions")
    assert sorted(positions) == list(range(world.num_frames))
    for f in (0, 7, 11):
        np.testing.assert_allclose(np.asarray(positions[f]), vertices[1, f], atol=1e-5)
    translations = column(chunks, "/world/camera", "translation")
    np.testing.assert_allclose(np.asarray([translations[f] for f in range(world.num_frames)]).reshape(-1, 3), camera_centres(world),
                               atol=1e-5)
    images = column(chunks, "/world/camera/image", "blob")
    assert len(images) == world.num_frames


def test_people_are_cleared_when_absent(recording):
    path, world, _, _ = recording
    chunks = rc.RrdReader(str(path)).stream().to_chunks()
    logged = column(chunks, "/world/people/0", "vertex_positions")
    assert 3 not in logged and 4 not in logged and 5 in logged
    cleared = column(chunks, "/world/people/0", "is_recursive")
    assert 3 in cleared
    # Re-appearing: faces are logged again with the vertices.
    faces = column(chunks, "/world/people/0", "triangle_indices")
    assert sorted(faces) == [0, 5]


def test_errors(small_scene, body, tmp_path):
    world = small_scene.world
    vertices, joints = posed_people(world, body)
    with pytest.raises(InputError, match="leading shape"):
        write_rrd(tmp_path / "x.rrd", world, vertices[:1], joints, body.faces, np.eye(3))
    with pytest.raises(InputError, match="ends before frame 2"):
        write_rrd(tmp_path / "x.rrd", world, vertices, joints, body.faces, np.eye(3),
                  frames_rgb=iter_frames(small_scene.video_path, 0, 2))
    assert not (tmp_path / "x.rrd").exists() and not list(tmp_path.iterdir())
