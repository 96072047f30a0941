"""Multi-THuMBS: multi-person, multi-shot human mesh reconstruction in one world frame.

Conventions (cameras, units, frames, SMPL order) are stated once in :mod:`multithumbs.conventions`.
"""

__version__ = "0.1.0"
