"""The head's colours as a facing cue: a face (skin under hair) against the back of a head (hair only),
read from hand-drawn pictures whose shading varies across the head, and undecided where hair is skin."""

import numpy as np
import pytest

from multithumbs.perception.head_colour import (HeadColourConfig, colour_distance, colour_features, face_evidence,
                                                head_samples)

SKIN = np.array([235.0, 190.0, 160.0])
HAIR = np.array([90.0, 55.0, 30.0])
H, W = 120, 320


def _person(middle: np.ndarray, crown: np.ndarray, hands: np.ndarray, neck_px: float = 30.0, shade: float = 0.75,
            x: float = 80.0):
    """One frame of a person drawn as flat discs about ``x``: head middle, crown, hands; its landmarks and
    packed mask. Lit from above: the brightness falls from 1 at the top of the head to ``shade`` at the chin
    and stays there below."""
    frame = np.full((H, W, 3), 40.0)
    mask = np.zeros((H, W), bool)
    ys, xs = np.mgrid[:H, :W]
    ears, shoulders = np.array([x, 40.0]), np.array([x, 40.0 + neck_px])
    hands_at = (np.array([x - 40, 100.0]), np.array([x + 40, 100.0]))

    def disc(centre, radius, colour):
        inside = (xs - centre[0]) ** 2 + (ys - centre[1]) ** 2 <= radius ** 2
        frame[inside], mask[inside] = colour, True

    disc(ears + [0, 0.5 * neck_px], 0.45 * neck_px, SKIN)        # neck and chin
    disc(ears + [0, -0.3 * neck_px], 0.45 * neck_px, crown)      # the skull's top half
    disc(ears + [0, 0.05 * neck_px], 0.3 * neck_px, middle)      # the head's middle
    for hand in hands_at:
        disc(hand, 4, hands)
    top, chin = ears[1] - 0.75 * neck_px, ears[1] + 0.35 * neck_px
    frame *= np.clip(1.0 - (1.0 - shade) * (ys - top) / (chin - top), shade, 1.0)[..., None]
    image = np.zeros((33, 5))
    image[:, 3:] = 1.0
    image[[7, 8], :2] = ears + [[-8, 0], [8, 0]]
    image[[11, 12], :2] = shoulders + [[-20, 0], [20, 0]]
    for landmarks, hand in zip(((15, 17, 19), (16, 18, 20)), hands_at):
        image[list(landmarks), :2] = hand
    return frame.clip(0, 255).astype(np.uint8), image, np.packbits(mask, axis=-1)


def _evidence(people, config=HeadColourConfig()):
    """Cue ``(P, T)`` for ``people``: per person a list of frames from :func:`_person`."""
    t = len(people[0])
    frames = [np.maximum.reduce([people[p][i][0] for p in range(len(people))]) for i in range(t)]
    image = np.stack([np.stack([f[1] for f in person]) for person in people])
    masks = np.stack([np.stack([f[2] for f in person]) for person in people])
    samples = head_samples(frames, image, masks, np.ones(image.shape[:2], bool), config)
    return face_evidence(samples, config), samples


def test_brightness_alone_does_not_move_chromaticity_and_counts_by_its_log():
    rgb = np.array([[200.0, 100.0, 50.0], [100.0, 50.0, 25.0]])
    features = colour_features(rgb)
    np.testing.assert_allclose(features[0, :2], features[1, :2], atol=2e-3)
    assert colour_distance(features[0], features[1]) == pytest.approx(np.log(351 / 176) / 0.5, rel=1e-3)
    assert features.shape == (2, 3) and colour_features(np.zeros((4, 5, 3))).shape == (4, 5, 3)


def test_a_face_reads_plus_one_and_the_back_of_a_head_minus_one_under_a_top_light():
    face = [_person(SKIN, HAIR, SKIN) for _ in range(4)]
    back = [_person(HAIR, HAIR, SKIN, x=240.0) for _ in range(4)]
    evidence, samples = _evidence([face, back])
    assert samples.shape == (2, 4, 3, 3) and np.isfinite(samples).all()
    np.testing.assert_array_equal(evidence, [[1, 1, 1, 1], [-1, -1, -1, -1]])


def test_undecided_where_hair_is_skin_the_head_is_small_or_the_cue_is_off():
    shaven = [_person(SKIN, SKIN, SKIN) for _ in range(4)]
    assert not _evidence([shaven])[0].any()
    small = [_person(SKIN, HAIR, SKIN, neck_px=5.0) for _ in range(4)]
    evidence, samples = _evidence([small])
    assert not evidence.any() and np.isnan(samples).all()
    face = [_person(SKIN, HAIR, SKIN) for _ in range(4)]
    assert not _evidence([face], HeadColourConfig(enabled=False))[0].any()
    # Fewer frames with seen hands than the contrast needs: undecided.
    assert not _evidence([face[:2]])[0].any()


def test_hidden_ears_leave_the_frame_unsampled():
    frames = [_person(SKIN, HAIR, SKIN) for _ in range(4)]
    frame, image, mask = frames[0]
    image = image.copy()
    image[7, 3] = 0.2
    frames[0] = (frame, image, mask)
    evidence, samples = _evidence([frames])
    assert np.isnan(samples[0, 0, :2]).all() and evidence[0, 0] == 0
    np.testing.assert_array_equal(evidence[0, 1:], 1)
