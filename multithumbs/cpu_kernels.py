"""One kernel choice on every x86-64 machine with AVX2, so that a content key means the same bytes anywhere.

MKL, torch's ATen, numpy, OpenBLAS and OpenCV each pick their kernels by the CPU they find, and two
kernels of one operation round differently. Measured (docs/RESULTS.md, session 10): on an AMD EPYC the
standard suite's s09 scored 120.90 mm and on an earlier machine 118.09 mm, from the same code; with MKL
in its conditional-numerical-reproducibility mode for AVX2 (``MKL_CBWR=AVX2``) the AMD machine gives
118.09 mm too. ``ATEN_CPU_CAPABILITY`` moved s01 by 0.014 mm on its own (``default`` against ``avx2``).

:func:`pin_cpu_kernels` sets each library's switch to its AVX2 (x86-64-v3) kernels, before the library
reads it: numpy and OpenBLAS read theirs when loaded, MKL at its first call, ATen at its first dispatch.
``multithumbs/__init__`` calls it first thing, so importing any part of the package before numpy or torch
have computed pins them. A machine without AVX2 (or not x86-64) is left alone: forcing AVX2 kernels there
would stop the process, and its bytes are told apart by :func:`kernel_tag`, which every artifact key
hashes. A value the user set beforehand is kept (their choice), and the tag then says so.
Not pinned: the tflite runtime's XNNPACK (BlazePose), which has no switch; the perception stage's key
hashes :func:`network_kernel_tag` for it. pycolmap is built without run-time dispatch.
"""

from __future__ import annotations

import functools
import os
import platform
import sys
from typing import Mapping, MutableMapping

PINS: Mapping[str, str] = {
    "MKL_CBWR": "AVX2",
    "ATEN_CPU_CAPABILITY": "avx2",
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
    "OPENBLAS_CORETYPE": "Haswell",
}
"""Environment variable -> the value that selects each library's AVX2 kernels (or turns its AVX-512 ones off)."""

_SKX_FLAGS = frozenset({"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"})
OPENCV_TARGETS: tuple[tuple[str, frozenset[str]], ...] = (
    ("AVX512-SKX", _SKX_FLAGS), ("AVX512-CLX", _SKX_FLAGS | {"avx512_vnni"}))
"""The AVX-512 targets OpenCV's wheels dispatch to (``cv2.getCPUFeaturesLine()``: ``... *AVX2 *AVX512-SKX
*AVX512-CLX``; disabling one does not disable the other), each with the CPU flags it needs. OpenCV spells
them with a hyphen: the underscored names it called "unknown" on every import, and disabled nothing."""
OPENCV_PIN: Mapping[str, str] = {"OPENCV_CPU_DISABLE": ",".join(name for name, _ in OPENCV_TARGETS)}
"""OpenCV's AVX-512 kernels turned off, on a CPU that has them all."""


def _opencv_pin(flags: frozenset[str]) -> dict[str, str]:
    """``OPENCV_CPU_DISABLE`` of the targets this CPU has (OpenCV warns on every import about turning off
    one it lacks), or nothing."""
    names = [name for name, needed in OPENCV_TARGETS if needed <= flags]
    return {"OPENCV_CPU_DISABLE": ",".join(names)} if names else {}


def pins_for(flags: frozenset[str]) -> dict[str, str]:
    """The variables :func:`pin_cpu_kernels` sets on a CPU with these flags (which must :func:`can_pin`)."""
    return {**PINS, **_opencv_pin(flags)}


PINNED_TAG = "x86-64-v3"
""":func:`kernel_tag` of a process whose libraries all use the pinned kernels."""


@functools.lru_cache(maxsize=None)
def cpu_flags(cpuinfo: str = "/proc/cpuinfo") -> frozenset[str]:
    """The first processor's feature flags (Linux); empty where the file is missing."""
    try:
        with open(cpuinfo) as fh:
            for line in fh:
                if line.startswith("flags"):
                    return frozenset(line.split(":", 1)[1].split())
    except OSError:
        pass
    return frozenset()


@functools.lru_cache(maxsize=None)
def cpu_model(cpuinfo: str = "/proc/cpuinfo") -> str:
    """The first processor's model name (Linux), else :func:`platform.processor`."""
    try:
        with open(cpuinfo) as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def can_pin(flags: frozenset[str], machine: str) -> bool:
    """Whether the pinned kernels run here: x86-64 with AVX2 and FMA."""
    return machine.lower() in ("x86_64", "amd64") and {"avx2", "fma"} <= flags


def pin_cpu_kernels(environ: MutableMapping[str, str] = os.environ, flags: frozenset[str] | None = None,
                    machine: str | None = None) -> dict[str, str]:
    """Set every :data:`PINS` variable the user has not set, where the CPU can run them; returns the ones set."""
    flags = cpu_flags() if flags is None else flags
    if not can_pin(flags, platform.machine() if machine is None else machine):
        return {}
    added = {name: value for name, value in pins_for(flags).items() if name not in environ}
    environ.update(added)
    return added


def kernel_tag(environ: Mapping[str, str] = os.environ) -> str:
    """:data:`PINNED_TAG` when every pin is in effect in this process; else a description of this CPU and the
    switches that differ, so that bytes made with other kernels never share a key with the pinned ones."""
    flags = cpu_flags()
    differing = sorted(name for name, value in pins_for(flags).items() if environ.get(name) != value)
    numpy_v4 = _numpy_has_avx512()
    if can_pin(flags, platform.machine()) and not differing and not numpy_v4:
        return PINNED_TAG
    return "unpinned:" + ";".join([platform.machine(), cpu_model(), *(f"{n}={environ.get(n, '')}" for n in differing),
                                   f"numpy_x86_v4={numpy_v4}"])


def network_kernel_tag(flags: frozenset[str] | None = None) -> str:
    """The instruction set the tflite runtime's XNNPACK (BlazePose) computes with: it picks its kernels by
    the CPU and has no switch, so the perception stage's key hashes this instead (``avx512``, ``avx2`` or
    ``baseline``)."""
    flags = cpu_flags() if flags is None else flags
    return "avx512" if "avx512f" in flags else "avx2" if {"avx2", "fma"} <= flags else "baseline"


def _numpy_has_avx512() -> bool:
    """Whether the loaded numpy dispatches to its AVX-512 kernels (it read its switch before the pin)."""
    if "numpy" not in sys.modules:
        return False
    try:
        from numpy._core._multiarray_umath import __cpu_features__
    except ImportError:
        return False
    return bool(__cpu_features__.get("X86_V4", False))


__all__ = ["PINS", "OPENCV_TARGETS", "OPENCV_PIN", "pins_for", "PINNED_TAG", "cpu_flags", "cpu_model", "can_pin", "pin_cpu_kernels", "kernel_tag", "network_kernel_tag"]
