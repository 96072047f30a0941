"""Real datasets: multi-view captures with SMPL ground truth, the multi-shot benchmark built from them,
and edited real videos for the GT-free metrics. Formats: ``docs/FORMATS.md``.

- :mod:`~multithumbs.datasets.cameras`: calibrated cameras (fisheye / radial distortion through OpenCV).
- :mod:`~multithumbs.datasets.sequence`: :class:`MultiViewSequence`, :class:`PeopleSeries`.
- :mod:`~multithumbs.datasets.egohumans`: EgoHumans and Harmony4D (COLMAP + Aria or ``scale.npy``).
- :mod:`~multithumbs.datasets.egobody`: EgoBody (Kinect views, gendered SMPL fits).
- :mod:`~multithumbs.datasets.clip_specs`: clip specs (:class:`ClipSpec`, spec files).
- :mod:`~multithumbs.datasets.benchmark`: the clip builder, :func:`iter_benchmark`.
- :mod:`~multithumbs.datasets.edited`: AVA (Multishot) and sitcom clips with cross-shot identities.
- :mod:`~multithumbs.datasets.catalog`: what a data root holds; opening a sequence.
- :mod:`~multithumbs.datasets.smpl_files`: converting an official SMPL pickle, verified.
"""

import importlib

# Names resolve lazily (PEP 562): the CLI imports this package's commands without paying for torch.
_EXPORTS = {"ClipSpec": "clip_specs", "build_clip": "benchmark", "iter_benchmark": "benchmark",
            "load_spec": "clip_specs", "load_specs": "clip_specs", "Camera": "cameras", "metric_extrinsics": "cameras",
            "describe_root": "catalog", "detect_dataset": "catalog", "open_sequence": "catalog",
            "MultiViewSequence": "sequence", "PeopleSeries": "sequence"}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
