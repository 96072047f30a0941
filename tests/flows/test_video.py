"""The real-video flow: shots, camera trajectories and shared spaces from pixels, people from a PHALP file."""

import json

import pytest

from multithumbs.synth.scene import SceneConfig

SCENE = SceneConfig(name="pixels", num_people=2, num_shots=2, num_frames=24, seed=7, image_size=(180, 320),
                    cut_angle_deg=35)


@pytest.fixture(scope="module")
def scene_files(tmp_path_factory):
    from multithumbs.body.model import load_body_model
    from multithumbs.perception.phalp_export import export_phalp
    from multithumbs.synth.files import write_synthetic
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.scene import synthesize

    out = tmp_path_factory.mktemp("pixels")
    body = load_body_model()
    video = synthesize(SCENE, body)
    write_synthetic(out, video)
    tracks = simulate_perception(video, body)
    export_phalp(out / "perception.pkl", tracks, video.truth.world.shots(), body)
    K = video.truth.world.K[0]
    return out, [K[0, 0], K[1, 1], K[0, 2], K[1, 2]]


def test_video_flow_from_pixels_then_from_the_store(prefect, tmp_path, scene_files):
    from flows.video import reconstruct_video
    from storage.store import ArtifactStore

    src, intrinsics = scene_files
    args = dict(video=str(src / "video.mp4"), out_dir=str(tmp_path / "out"), store_url=str(tmp_path / "store"),
                perception=f"phalp:{src / 'perception.pkl'}", trust_pickle=True, intrinsics=intrinsics,
                truth=str(src / "ground_truth.npz"))
    summary = reconstruct_video(**args)
    assert summary["num_shots"] == 2 and summary["backends"]["shots"] == "scenedetect:adaptive"
    assert summary["backends"]["shared space"] == "pycolmap"
    assert summary["metrics"]["ids"] == 0 and summary["metrics"]["w_mpjpe"] < 400
    for name in ("result.npz", "metrics.json", "overlay.mp4", "report.md", "scene.glb", "trajectory.png"):
        assert (tmp_path / "out" / name).stat().st_size > 0, name
    assert "pycolmap" in (tmp_path / "out" / "report.md").read_text()
    store = ArtifactStore(tmp_path / "store")
    stages = sorted(store.record(k)["stage"] for k in store.keys())
    assert stages == sorted(["ground_truth", "shots", "perception", "perception", "trajectory", "trajectory", "space",
                             "align", "propagate", "reid", "post", "evaluate"])
    created = {k: store.record(k)["created"] for k in store.keys()}
    again = reconstruct_video(**args)
    assert {k: store.record(k)["created"] for k in store.keys()} == created
    assert json.dumps(again["metrics"], sort_keys=True) == json.dumps(summary["metrics"], sort_keys=True)


def test_plain_python_chain_matches_the_flow(prefect, tmp_path, scene_files):
    """`run_video_file` (no Prefect) and the flow run the same stages: the same identities and geometry."""
    import numpy as np

    from flows.video import reconstruct_video
    from multithumbs.body.model import load_body_model
    from multithumbs.io import load_result
    from multithumbs.pipeline import run_video_file

    src, (fx, fy, cx, cy) = scene_files
    K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    plain = run_video_file(src / "video.mp4", f"phalp:{src / 'perception.pkl'}", load_body_model(), K,
                           trust_pickle=True)
    reconstruct_video(str(src / "video.mp4"), str(tmp_path / "out"), str(tmp_path / "store"),
                      f"phalp:{src / 'perception.pkl'}", True, [fx, fy, cx, cy])
    flowed = load_result(tmp_path / "out" / "result.npz")
    np.testing.assert_array_equal(plain.id_map, flowed.id_map)
    np.testing.assert_allclose(plain.transl, flowed.transl, atol=1e-3)


def test_focal_length_withheld_is_estimated_and_keyed(prefect, tmp_path, scene_files):
    """No intrinsics: the flow's 'focal' stage estimates them as `run_video_file` does, and says from what."""
    import numpy as np

    from flows.video import reconstruct_video
    from multithumbs.body.model import load_body_model
    from multithumbs.pipeline import run_video_file
    from storage.store import ArtifactStore

    src, _ = scene_files
    spec = f"phalp:{src / 'perception.pkl'}"
    summary = reconstruct_video(str(src / "video.mp4"), str(tmp_path / "out"), str(tmp_path / "store"), spec, True)
    store = ArtifactStore(tmp_path / "store")
    assert sorted(store.record(k)["stage"] for k in store.keys()).count("focal") == 2  # motion, then final
    focal = summary["focal"]
    assert focal["source"] in ("moving_camera", "lines", "heights", "default") and focal["focal_px"] > 0
    assert summary["backends"]["focal length"].startswith(f"focal length {focal['focal_px']:.0f} px (")
    plain = run_video_file(src / "video.mp4", spec, load_body_model(), None, trust_pickle=True)
    assert str(plain.diagnostics["focal_source"]) == focal["source"]
    np.testing.assert_allclose(float(plain.diagnostics["focal_px"]), focal["focal_px"], rtol=1e-9)
