"""Seconds per 640x360 frame of the synthetic renderer, on one core.

Renders a short camera orbit in a generated room, first empty, then with three person-sized meshes of
about 3,000 vertices / 6,000 faces each (capsules, built here so the benchmark does not depend on the
body model), and prints the median time per frame after a warm-up frame.

    .venv/bin/python benchmarks/render_frame.py [--runs 9] [--seed 0]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, before numpy loads its BLAS

import argparse
import statistics
import time

import cv2
import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels, multithumbs/cpu_kernels.py)
import numpy as np
import trimesh

from multithumbs.geometry import intrinsics_from_fov, look_at
from multithumbs.synth.render import MeshInstance, render_view
from multithumbs.synth.room import make_room
from multithumbs.synth.textures import texture_atlas

IMAGE_SIZE = (360, 640)


def person_mesh(position: tuple[float, float], colour: tuple[float, float, float]) -> MeshInstance:
    """A 1.7 m capsule 'person' (3,074 vertices, 6,144 faces) standing at ``position`` on the floor."""
    capsule = trimesh.creation.capsule(height=1.25, radius=0.22, count=[48, 64])
    vertices = np.asarray(capsule.vertices) * [1.0, 0.65, 1.0] + [position[0], position[1], 0.845]
    colours = np.tile(colour, (len(vertices), 1))
    colours[vertices[:, 2] > 1.45] = (0.9, 0.72, 0.58)  # head
    return MeshInstance(vertices, np.asarray(capsule.faces), colours)


def time_frames(room, meshes, cameras, K) -> list[float]:
    times = []
    for R, t in cameras:
        start = time.perf_counter()
        render_view(room, meshes, K, R, t, IMAGE_SIZE)
        times.append(time.perf_counter() - start)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=9, help="timed frames per case (>= 5)")
    parser.add_argument("--seed", type=int, default=0, help="room seed")
    args = parser.parse_args()
    cv2.setNumThreads(1)

    start = time.perf_counter()
    room = make_room(args.seed)
    texture_atlas(room)
    setup = time.perf_counter() - start

    K = intrinsics_from_fov(IMAGE_SIZE[1], IMAGE_SIZE[0], 70.0)
    cameras = []
    for azimuth in np.linspace(180.0, 240.0, max(args.runs, 5)):
        a = np.deg2rad(azimuth)
        cameras.append(look_at(np.array([3.0 * np.cos(a), 2.6 * np.sin(a), 1.7]), np.array([0.0, 0.0, 1.0])))
    meshes = [person_mesh((0.6, 0.4), (0.8, 0.2, 0.2)), person_mesh((-0.7, -0.3), (0.2, 0.45, 0.8)),
              person_mesh((0.1, 1.2), (0.3, 0.7, 0.3))]

    render_view(room, meshes, K, *cameras[0], IMAGE_SIZE)  # warm-up
    empty = time_frames(room, [], cameras, K)
    people = time_frames(room, meshes, cameras, K)
    sizes = f"{len(meshes[0].vertices)} vertices / {len(meshes[0].faces)} faces each"
    print(f"room generation + texture atlas (once per scene): {setup:.3f} s")
    print(f"room only          : median {statistics.median(empty):.4f} s/frame over {len(empty)} frames")
    print(f"room + 3 meshes    : median {statistics.median(people):.4f} s/frame over {len(people)} frames ({sizes})")


if __name__ == "__main__":
    main()
