import numpy as np
import torch

from multithumbs.body.model import load_body_model
from multithumbs.perception.oracle import oracle_tracks
from multithumbs.synth.scene import SceneConfig, synthesize


def test_oracle_tracks_pose_the_true_bodies_in_each_camera():
    body = load_body_model()
    video = synthesize(SceneConfig(num_people=2, num_shots=2, num_frames=8, image_size=(90, 160), seed=3), body)
    world = video.truth.world
    tracks = oracle_tracks(video.truth, body)
    assert [tr.num_frames for tr in tracks] == [b - a for a, b in world.shots().ranges]
    for tr in tracks:
        for i, p in enumerate(tr.track_ids):
            f = int(np.flatnonzero(tr.valid[i])[0])
            frame = tr.start_frame + f
            with torch.no_grad():
                cam = body.joints(tr.global_orient[i, f], tr.body_pose[i, f], tr.betas[i], tr.transl[i, f]).numpy()
                wld = body.joints(world.global_orient[p, frame], world.body_pose[p, frame], world.betas[p],
                                  world.transl[p, frame]).numpy()
            expected = wld @ world.R[frame].T + world.t[frame]
            np.testing.assert_allclose(cam, expected, atol=1e-5)
