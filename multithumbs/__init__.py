"""Multi-THuMBS: multi-person, multi-shot human mesh reconstruction in one world frame.

Conventions (cameras, units, frames, SMPL order) are stated once in :mod:`multithumbs.conventions`.
"""

from multithumbs.cpu_kernels import pin_cpu_kernels

pin_cpu_kernels()  # before numpy or torch compute: the same kernels, so the same bytes, on any AVX2 machine

__version__ = "0.1.0"
