"""Identity switches of the full method and the re-ID baselines on the dressed-alike scenes, over several
perception seeds (one seed's ties between identical clothes can fall right by chance).

Usage: python benchmarks/reid_seeds.py [--seeds 5] [--scenes s08_dressed_alike s12_alike_crossing_25deg]
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor

from multithumbs.bench import run_scene
from multithumbs.synth.suite import suite_scene

VARIANTS = ("full", "appearance_only", "distance_only")


def _one(args):
    scene, seed = args
    import torch

    torch.set_num_threads(1)
    scores = run_scene(suite_scene("standard", scene), VARIANTS, seed=seed)
    return scene, seed, {v: scores.metrics[v]["ids"] for v in VARIANTS}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--scenes", nargs="+", default=["s08_dressed_alike", "s12_alike_crossing_25deg"])
    args = parser.parse_args()
    jobs = [(s, k) for s in args.scenes for k in range(args.seeds)]
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(_one, jobs))
    for scene, seed, ids in rows:
        print(f"{scene} seed {seed}: " + ", ".join(f"{v} {ids[v]:.0f}" for v in VARIANTS))
    for v in VARIANTS:
        total = sum(ids[v] for _, _, ids in rows)
        clean = sum(ids[v] == 0 for _, _, ids in rows)
        print(f"{v}: {total:.0f} switches in {len(rows)} runs; zero-switch runs {clean}/{len(rows)}")


if __name__ == "__main__":
    main()
