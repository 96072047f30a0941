"""The one statement of Multi-THuMBS conventions. Every module follows it; edges convert.

Cameras
    OpenCV pinhole. Extrinsics map world to camera, ``x_cam = R @ x_world + t`` with column vectors;
    the camera centre is ``C = -R.T @ t``. Camera axes: +x right, +y down, +z forward (viewing
    direction). Intrinsics ``K`` are 3x3 in pixels; pixel ``(u, v)`` has its centre at integer
    coordinates (``u`` along the width, ``v`` along the height), so pixel ``(0, 0)`` covers
    ``[-0.5, 0.5]^2``. The paper writes ``[R|C]``; convert at the edge with
    :func:`multithumbs.geometry.camera_centre`. COLMAP puts pixel centres at ``+0.5``: add 0.5 to
    ``cx, cy`` when handing a camera to pycolmap.

Worlds
    Synthetic and ground-truth worlds are metric with +z up and the floor at ``z = 0``. A
    reconstructed world is whatever frame the method chose (the first boundary's shared space);
    metrics align it to the truth with Sim(3) where the metric says so.

Units
    Metres, radians, seconds. Frames are indexed from 0 at the video's native fps. A cut at ``t_b``
    means frame ``t_b`` is the first frame of the new shot; the boundary pair is ``(t_b - 1, t_b)``.
    Shot ``k`` spans ``[cuts[k-1], cuts[k])`` with ``cuts[-1] = 0`` and ``cuts[K] = T`` implied.

SMPL
    24 joints in SMPL order (0 pelvis, 1 left hip, 2 right hip, 3 spine1, 4 left knee, 5 right knee,
    6 spine2, 7 left ankle, 8 right ankle, 9 spine3, 10 left foot, 11 right foot, 12 neck,
    13 left collar, 14 right collar, 15 head, 16 left shoulder, 17 right shoulder, 18 left elbow,
    19 right elbow, 20 left wrist, 21 right wrist, 22 left hand, 23 right hand). The body model's own
    frame is SMPL's: +y up, the body faces +z, its left is +x. The root is the pelvis (joint 0);
    ``global_orient`` rotates the body about the pelvis and ``transl`` is added to every vertex, as
    in ``smplx``. Rotations are axis-angle ``(..., 3)`` at the edges (files, contracts) and rotation
    matrices ``(..., 3, 3)`` or 6D inside optimizers. ``body_pose`` is ``(..., 23, 3)``;
    ``betas`` has 10 entries per person and does not change over time.

Shapes and missing data
    Functions are batch-agnostic: leading ``...`` dimensions pass through. Per-person time series are
    padded arrays ``(P, T, ...)`` with a boolean ``valid (P, T)``; missing data is a mask, never a
    magic number. Masks are stored bit-packed along the image width (``numpy.packbits``).

Images
    ``(H, W, 3)`` uint8 RGB. Depth maps are ``(H, W)`` float32 z-depth in metres along the camera's
    +z axis, ``inf`` where nothing was hit.
"""

SMPL_JOINT_NAMES: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "left_hand", "right_hand",
)
"""SMPL's 24 joints in order."""

SMPL_PARENTS: tuple[int, ...] = (
    -1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21,
)
"""Parent of each SMPL joint in the kinematic tree (-1 for the root)."""

NUM_JOINTS = 24
NUM_BODY_JOINTS = 23
NUM_BETAS = 10
