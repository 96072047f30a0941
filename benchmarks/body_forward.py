"""Time the body model's forward pass (smplx LBS over the procedural body by default).

Prints the vertex count and the median wall time over several runs, after a warm-up, of one forward
pass for a batch of frames (float32, CPU): under ``torch.no_grad``, with gradients enabled, and forward
plus backward. Usage: ``python benchmarks/body_forward.py [--batch 600] [--runs 7] [--model PATH]``.
"""

from __future__ import annotations

import argparse
import statistics
import time

import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels, multithumbs/cpu_kernels.py)
import torch

from multithumbs.body.model import BodyModel


def median_seconds(run, runs: int) -> float:
    """Median wall time of ``run()`` over ``runs`` calls after one warm-up call."""
    run()
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=600, help="frames per forward pass")
    parser.add_argument("--runs", type=int, default=7, help="timed runs (median reported), at least 5")
    parser.add_argument("--model", default=None, help="SMPL file (default: $MULTITHUMBS_SMPL_MODEL or procedural)")
    args = parser.parse_args()

    body = BodyModel(args.model)
    generator = torch.Generator().manual_seed(0)
    orient = torch.randn(args.batch, 3, generator=generator) * 0.3
    pose = torch.randn(args.batch, 23, 3, generator=generator) * 0.3
    betas = torch.randn(args.batch, 10, generator=generator)
    transl = torch.randn(args.batch, 3, generator=generator)
    runs = max(5, args.runs)

    def no_grad():
        with torch.no_grad():
            body(orient, pose, betas, transl)

    inputs = [x.clone().requires_grad_() for x in (orient, pose, betas, transl)]

    def with_grad():
        body(*inputs)

    def with_backward():
        out = body(*inputs)
        (out.vertices.square().sum() + out.joints.square().sum()).backward()

    print(f"body: {body.source}, {body.num_vertices} vertices, {len(body.faces)} faces; "
          f"batch {args.batch} frames, float32, CPU, {torch.get_num_threads()} threads, median of {runs}")
    for name, run in (("forward, no_grad", no_grad), ("forward, with grad", with_grad),
                      ("forward + backward", with_backward)):
        seconds = median_seconds(run, runs)
        print(f"{name:20s} {seconds * 1e3:8.1f} ms  ({seconds * 1e3 / args.batch:.3f} ms/frame)")


if __name__ == "__main__":
    main()
