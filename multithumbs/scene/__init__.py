"""Scene geometry from pixels: shots (scenedetect), camera trajectories and shared spaces (pycolmap),
learned scene priors (VGGT, Depth-Anything-3). Public API re-exported here; heavy imports stay lazy."""

import importlib

# Names resolve lazily (PEP 562): the CLI imports this package's commands without loading pycolmap.
_EXPORTS = {"SceneGeometry": "geometry", "scene_geometry": "geometry", "BoundaryPair": "shots", "ShotConfig": "shots",
            "boundary_frames": "shots", "detect_shots": "shots", "TrackingConfig": "tracking",
            "track_camera": "tracking", "TwoViewConfig": "two_view_pose", "default_intrinsics": "two_view",
            "shared_space_at_cut": "two_view"}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
