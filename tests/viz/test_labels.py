"""Labels: the dark outline lies around the white text, not beside it (issue 19: "frame 533 shot 1 1")."""

from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from multithumbs.synth.files import contact_sheet
from multithumbs.viz.labels import draw_label, outline_radius
from multithumbs.viz.overlay import PeopleLayer, annotate

GREY = 128


def assert_outline_around_text(picture: np.ndarray, slack: int) -> None:
    """White text pixels all touch the outline, every outline pixel is near the text, and their boxes agree."""
    white = (picture > 150).all(axis=-1)  # mostly-covered text pixels: thin strokes of small text stay below 200
    dark = (picture < 50).all(axis=-1)
    assert white.sum() > 30 and dark.sum() > white.sum()
    near_dark = cv2.dilate(dark.astype(np.uint8), np.ones((2 * slack + 1,) * 2, np.uint8)).astype(bool)
    near_white = cv2.dilate(white.astype(np.uint8), np.ones((2 * slack + 1,) * 2, np.uint8)).astype(bool)
    assert near_dark[white].all(), "white text outside the outline"
    assert near_white[dark].all(), "outline pixels away from the text (a ghost copy)"
    box = lambda m: np.array([np.nonzero(m)[1].min(), np.nonzero(m)[0].min(),  # noqa: E731
                              np.nonzero(m)[1].max(), np.nonzero(m)[0].max()])
    margin = (box(white) - box(dark)) * np.array([1, 1, -1, -1])  # outline beyond the text, per side
    assert (margin >= 0).all() and (margin <= slack).all(), margin
    assert abs(margin[0] - margin[2]) <= 1, f"outline off-centre horizontally: {margin}"


@pytest.mark.parametrize("scale", [0.35, 0.5, 0.58, 1.0, 1.6])
def test_draw_label_outline_is_around_the_text(scale):
    image = np.full((int(60 * scale) + 30, int(520 * scale) + 40, 3), GREY, np.uint8)
    draw_label(image, "result  frame 533  shot 1", (10, int(30 * scale) + 12), scale)
    assert_outline_around_text(image, outline_radius(scale) + 1)


def test_draw_label_clips_at_the_border():
    image = np.full((30, 60, 3), GREY, np.uint8)
    draw_label(image, "#12", (-8, 5), 0.8, (255, 0, 0))  # half outside: drawn where it lands, no error
    draw_label(image, "#3", (500, 500), 0.8)  # wholly outside: nothing drawn
    assert image.shape == (30, 60, 3) and (image != GREY).any()


def test_contact_sheet_labels_are_not_ghosted():
    frames = np.full((12, 90, 160, 3), GREY, np.uint8)
    video = SimpleNamespace(frames=frames, scene=SimpleNamespace(cut_frames=np.array([6])))
    sheet = contact_sheet(video, per_shot=3, tile_width=320)
    tile_h = 180 + 6
    for row in range(2):  # the first tile of each shot row, label strip only (inside the border)
        assert_outline_around_text(sheet[row * tile_h + 3:row * tile_h + 30, 3:200], outline_radius(0.5) + 1)


def test_overlay_header_is_not_ghosted(small_scene):
    world = small_scene.world
    h, w = world.image_size
    image = np.full((h, w, 3), GREY, np.uint8)
    empty = PeopleLayer(np.zeros((h, w, 3), np.float32), np.full((h, w), -1, np.int16), np.zeros((0, 2)))
    annotate(image, world, 0, np.zeros(0, int), empty, title="result")
    assert_outline_around_text(image[:22, :w - 4], outline_radius(max(0.35, min(1.0, w / 1100))) + 1)
