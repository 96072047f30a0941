"""How people are found and followed within a shot: the settings of :mod:`.pose_tracking`."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TrackerConfig:
    """How people are found and followed within a shot."""

    min_detection_score: float = 0.5
    """Detector score at which a detection starts or revives a track (MediaPipe's pose solution: 0.5)."""
    min_presence: float = 0.5
    """Pose flag below which a person is lost in that frame (MediaPipe's ``min_tracking_confidence``)."""
    redetect_every: int = 1
    """Frames between whole-frame detections while everyone is followed (1: every frame, which finds
    people entering soonest; each detection costs ~12 ms beside ~25 ms per person for the landmarks)."""
    max_people: int = 8
    """Most people followed at once; the detector's weakest new detections wait beyond it."""
    max_missed: int = 15
    """Frames a lost person can be re-found under the same id (short occlusions)."""
    revive_iou: float = 0.3
    """Overlap of a new person's box with a lost one's last box that makes it the same person."""
    duplicate_iou: float = 0.6
    """Overlap of two people's landmark boxes that means they follow one person."""
    nested_fraction: float = 0.8
    """Share of the smaller of two landmark boxes inside the larger that also means one person."""
    mask_overlap: float = 0.7
    """Share of the smaller of two segmentations inside the other that also means one person."""
    min_height: float = 0.06
    """Smallest height of a detection's landmark box, as a share of the frame's, for it to start or revive
    a track: figures in the suite's posters (0.04 of the frame) read as people with a sure flag and were
    followed for seconds. ``vtest.avi``'s far pedestrians are 0.10 of its frame at the 10th percentile, and
    the smallest person the suite's figures count is 0.22 (80 px of 360)."""
    min_extent: float = 0.3
    """Smallest long side of a pose's landmark box, as a share of its square's side, for it to count."""
    max_roll: float = 1.5707963267948966
    """Largest turn from upright (radians; 90°) of the square a pose's own landmarks give for the pose to
    count: the suite's people, and the footage's, stand, walk and sit; readings past it took the feet for
    the head."""
    stitch_gap: int = 8
    """Most frames between the end of one track and the start of another for the second to continue the
    first once the shot is read (:mod:`.track_stitch`; 0: never)."""
    stitch_iou: float = 0.3
    """Overlap of the later track's first box with the earlier one's last box, moved on at its last
    velocity, for the two to be one person."""
    min_run: int = 3
    """Frames of a track outside a run of this many consecutive ones are dropped."""
    min_frames: int = 6
    """Tracks seen in fewer frames (a quarter second at 24 fps) are dropped: passing misreadings."""
    mask_probability: float = 0.5
    """Segmentation probability at which a pixel belongs to a person."""
    paint_probability: float = 0.3
    """Segmentation probability at which a found person's pixels are greyed out before the next detection."""
    tiles: int = 3
    """Square tiles across the frame's long side the detector also looks at when the whole frame gives
    nothing (below 2: whole frame only)."""
    proposals: bool = True
    """Also give a landmark pass to the people a whole-body person detector sees where no one is followed
    (:mod:`.person_proposals`; ``track_shot``'s ``people``, else OpenCV's HOG): the face-anchored detector
    misses people seen from behind or without a readable face (docs/RESULTS.md, sessions 15 and 17)."""
    proposal_every: int = 2
    """Frames between the person detector's looks (``track_shot``'s ``people``) on frames the tracker
    searches: NanoDet costs ~0.25 s a 640x360 frame on 2 cores (docs/RESULTS.md, session 17); every
    second frame keeps 4 people at 640x360 within 0.5 s a frame (session 19)."""
    proposal_behind: bool = True
    """Also read a proposal whose centre lies in a followed person's box (someone partly behind them) when
    it overlaps none of those boxes by ``proposal_same_iou``: on the frame with the followed greyed out."""
    proposal_same_iou: float = 0.5
    """Overlap of a proposal with a followed person's landmark box at which it is that person."""
    proposal_min_weight: float = 0.5
    """Smallest HOG SVM margin of a proposal (the suite's boxes score 0.25 to 2.4; people mostly above 0.5)."""
    proposal_scales: tuple[float, ...] = (1.0, 0.5)
    """Sizes of the frame HOG looks at: its 64x128 window finds people from 128 px tall at 1, 256 px at 0.5."""
    proposal_side: float = 1.2
    """Side of the landmark model's square for a bare proposal box, as a multiple of the box's height."""
    proposal_zoom: float = 1.1
    """Side of the crop around a proposal the face-anchored detector is asked again on, as a multiple of
    the box's height (0: not asked; its alignment points give a better square when it answers)."""
    max_rejections: int = 2
    """Detections a frame may reject (no pose in the landmark pass, someone already followed) before the
    search stops."""
    read_behind: bool = True
    """Read a followed person's square again, with the others read in it greyed out, when its reading is
    someone else's or another track's (:mod:`.behind`): someone partly behind another stays followed."""
    behind_max_roll: float = 0.7853981633974483
    """Largest turn from upright (radians; 45°) of the square a reading taken behind someone gives: a person
    behind another stands as they do. On the suite the readings behind others were within 5° of upright,
    and those past 70° were a rug read as a body lying on it, kept alive beside the person crossing it."""
    appearance: bool = True
    """Let each track's appearance model (:mod:`.track_appearance`) drop readings that slid onto someone
    else, settle which of two tracks on one person owns it, and pick which lost track is found again."""
    drift_dissimilarity: float = 0.6
    """Dissimilarity of a reading to its track's model above which the reading is someone else's (own
    person: 0.40 at the 95th percentile; others: 0.63 at the 10th)."""
    appearance_margin: float = 0.15
    """How much lower one track's dissimilarity must be than every other's for appearance to decide
    between them; below it the boxes decide (people dressed alike)."""
    relink_missed: int = 48
    """Frames (2 s at 24 fps) a lost person can be found again by appearance alone, when no lost track's
    last box overlaps them."""
    split_dissimilarity: float = 0.3
    """Dissimilarity of a reading to its track's model above which it is unlike the track's person: not
    learnt from, and ``split_frames`` such readings in a row mean the track has moved onto someone else."""
    split_frames: int = 3
    """Readings in a row unlike the track's model after which they become a new track, from the first of
    them, and the old track is lost where it was before them (a hidden person's square slid onto the
    person in front, whom no track followed)."""
    split_jump: float = 0.1
    """How far below ``split_dissimilarity`` the track's typical fit before those readings (the median of
    its last 5) must be for them to split it: a track whose readings always fitted so-so has not moved."""
    merge_splits: bool = True
    """Give a split-off track's frames back to the track it came from when ``split_frames`` of its readings
    in a row fit that track's model well again (:mod:`.track_split`: its own person read poorly)."""
    drop_transit: bool = True
    """Once the shot is read, drop the ``split_frames`` readings that split a track, when the split stands:
    the square was sliding from one person onto the other, and they are partly each (:mod:`.track_split`)."""
    relink_dissimilarity: float = 0.35
    """Largest dissimilarity at which appearance alone finds a lost person again."""
    isolation_iou: float = 0.05
    """A track's model learns only from frames where its box overlaps nobody else's by more than this."""
    model_memory: int = 20
    """Readings a model averages before it becomes a running mean of that length."""
    min_model_readings: int = 5
    """Readings a model needs (in a region) before it is asked anything (with 2, early models learnt from
    a few poor segmentations took the wrong side of a duplicate on the suite's dolly shot)."""
    backfill: int = 120
    """Frames each run of a track may be followed back from where it was found, once the shot is read
    (:mod:`.backfill`; 0: off)."""
    reread: int = 4
    """First frames of each run of a track read again, backwards from the frame after them, once the shot
    is read (:func:`.backfill.reread_starts`; 0: off): a run's first squares come from a detection, and
    the landmarks read in them are often a narrow, half-turned body until the square follows the person."""
