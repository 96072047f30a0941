"""A small synthetic scene, its simulated perception, its video file and a PHALP results file of it."""

from __future__ import annotations

import pytest

from multithumbs.synth.perception import NO_NOISE, simulate_perception
from multithumbs.synth.scene import SceneConfig, synthesize

SCENE = SceneConfig(num_people=2, num_shots=2, num_frames=16, image_size=(96, 160), seed=3)


@pytest.fixture(scope="session")
def scene(body):
    """``(video, shots)`` of a two-person, two-shot scene, 16 frames of 160x96."""
    video = synthesize(SCENE, body)
    return video, video.truth.world.shots()


@pytest.fixture(scope="session")
def perfect_tracks(scene, body):
    """Per-shot tracks of perfect perception (truth in each shot's camera frame)."""
    return simulate_perception(scene[0], body, NO_NOISE)


@pytest.fixture(scope="session")
def noisy_tracks(scene, body):
    """Per-shot tracks of the default simulated perception (shuffled ids, missed frames, eroded masks)."""
    return simulate_perception(scene[0], body, seed=1)


@pytest.fixture(scope="session")
def video_file(scene, tmp_path_factory):
    """The scene's video as an MPEG-4 file."""
    from multithumbs.synth.files import write_video

    video, _ = scene
    return write_video(tmp_path_factory.mktemp("video") / "video.mp4", video.frames, SCENE.fps)


@pytest.fixture(scope="session")
def results_file(scene, noisy_tracks, body, tmp_path_factory):
    """The noisy tracks written as a PHALP results file (``n_init=1``: every detection kept, for round trips)."""
    from multithumbs.perception.phalp_export import export_phalp

    return export_phalp(tmp_path_factory.mktemp("phalp") / "results.pkl", noisy_tracks, scene[1], body, n_init=1)


@pytest.fixture(scope="session")
def tiny_models(tmp_path_factory):
    """Tiny randomly initialised ViTPose and SAM models saved the way real checkpoints are (``save_pretrained``
    with their processors), so the adapters load them through the real ``from_pretrained`` path, offline."""
    import os

    import torch
    from transformers import (
        SamConfig,
        SamMaskDecoderConfig,
        SamModel,
        SamProcessor,
        SamPromptEncoderConfig,
        SamVisionConfig,
        VitPoseBackboneConfig,
        VitPoseConfig,
        VitPoseForPoseEstimation,
    )
    from transformers.models.sam.image_processing_pil_sam import SamImageProcessorPil
    from transformers.models.vitpose.image_processing_pil_vitpose import VitPoseImageProcessorPil

    os.environ["HF_HUB_OFFLINE"] = "1"
    root = tmp_path_factory.mktemp("models")
    torch.manual_seed(0)
    backbone = VitPoseBackboneConfig(image_size=(64, 48), patch_size=(16, 16), hidden_size=32, num_hidden_layers=2,
                                     num_attention_heads=2, mlp_ratio=2, out_indices=[2])
    VitPoseForPoseEstimation(VitPoseConfig(backbone_config=backbone, num_labels=17)).save_pretrained(root / "vitpose")
    VitPoseImageProcessorPil(size={"height": 64, "width": 48}).save_pretrained(root / "vitpose")
    VitPoseForPoseEstimation(VitPoseConfig(backbone_config=backbone, num_labels=5)).save_pretrained(root / "vitpose5")
    VitPoseImageProcessorPil(size={"height": 64, "width": 48}).save_pretrained(root / "vitpose5")
    sam = SamConfig(
        vision_config=SamVisionConfig(hidden_size=32, output_channels=16, num_hidden_layers=2, num_attention_heads=2,
                                      image_size=64, patch_size=8, window_size=4, global_attn_indexes=[1], mlp_dim=64,
                                      num_pos_feats=8),
        prompt_encoder_config=SamPromptEncoderConfig(hidden_size=16, image_size=64, patch_size=8, mask_input_channels=4),
        mask_decoder_config=SamMaskDecoderConfig(hidden_size=16, mlp_dim=32, num_hidden_layers=2, num_attention_heads=2,
                                                 iou_head_hidden_dim=16))
    SamModel(sam).save_pretrained(root / "sam")
    SamProcessor(image_processor=SamImageProcessorPil(size={"longest_edge": 64}, pad_size={"height": 64, "width": 64})
                 ).save_pretrained(root / "sam")
    return {"vitpose": root / "vitpose", "vitpose5": root / "vitpose5", "sam": root / "sam"}


@pytest.fixture
def one_torch_thread():
    """Tiny models run ~100x faster on one thread when the cores are shared (OpenMP spin); restored after."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)
