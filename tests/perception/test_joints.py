import numpy as np
import pytest

from multithumbs.conventions import SMPL_JOINT_NAMES
from multithumbs.perception.joints import (
    COCO17_NAMES,
    COCO17_TO_SMPL24,
    OPENPOSE25_TO_SMPL24,
    coco17_to_smpl24,
    openpose25_to_smpl24,
    smpl24_to_openpose,
)


def test_coco_names_match_smpl_names():
    for coco, smpl in COCO17_TO_SMPL24.items():
        assert COCO17_NAMES[coco] == SMPL_JOINT_NAMES[smpl]


def test_coco17_to_smpl24_shapes_and_zero_confidence():
    kp = np.random.default_rng(0).uniform(0.1, 1, (2, 5, 17, 3))
    out = coco17_to_smpl24(kp)
    assert out.shape == (2, 5, 24, 3)
    mapped = sorted(COCO17_TO_SMPL24.values())
    unmapped = [j for j in range(24) if j not in mapped]
    assert np.all(out[..., unmapped, 2] == 0)
    np.testing.assert_array_equal(out[..., 20, :], kp[..., 9, :])  # left wrist
    with pytest.raises(ValueError):
        coco17_to_smpl24(np.zeros((18, 3)))


def test_openpose_round_trip():
    kp = np.random.default_rng(1).uniform(0, 1, (4, 24, 2))
    back = openpose25_to_smpl24(smpl24_to_openpose(kp))
    joints = sorted(OPENPOSE25_TO_SMPL24.values())
    np.testing.assert_array_equal(back[:, joints], kp[:, joints])
    assert smpl24_to_openpose(kp).shape == (4, 45, 2)
    assert OPENPOSE25_TO_SMPL24[8] == 0  # mid-hip is SMPL's pelvis
