"""Appearance alone across cuts, with appearance computed from pixels of IMPORTED tracks.

For each scene of the standard suite: synthesise it, simulate per-shot perception (default noise), write
the video (MPEG-4) and the tracks as a 4DHumans/PHALP results file, import them back through
``load_perception("phalp:...")`` — which describes appearance from the decoded video's pixels with the
imported masks and PHALP's 2D joints — and run the appearance-only re-identification
(``variant_config("appearance_only")``: Hungarian on A alone, no distance gate) cut by cut with the
pipeline's own ``reidentify``. Each track is mapped to its true person by mask overlap.

Printed per scene: across all cuts, how many links were made, how many link a track to the wrong person
(identity switches; links between the two people of a dressed-alike pair are counted apart), and the same
for the simulated perception's own appearance (computed from the rendered frames, exact keypoints) as a
reference.

Usage: python benchmarks/appearance_reid.py [--scenes s01_two_people_20deg ...] [--workers 2]
"""

from __future__ import annotations

import argparse
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels, multithumbs/cpu_kernels.py)
import numpy as np


def _links(tracks, video, shots, body, alike):
    from multithumbs.pipeline import propagate, reidentify, variant_config
    from multithumbs.synth.perception import true_track_people
    from multithumbs.synth.simulated_geometry import simulate_camera_trajectory

    trajectories = [simulate_camera_trajectory(video, k) for k in range(shots.num_shots)]
    placement = propagate(shots, tracks, trajectories, [], body, independent=True)
    cfg = variant_config("appearance_only")
    ids = reidentify(tracks, placement, cfg.reid, cfg.appearance_window, shots.fps)
    truth = [true_track_people(tr, video) for tr in tracks]
    # global id -> true person, from the shot where the id was created
    owner: dict[int, int] = {}
    for k, gids in enumerate(ids.global_ids):
        for i, g in enumerate(gids):
            owner.setdefault(int(g), int(truth[k][i]))
    links = wrong = wrong_alike = 0
    for k in range(1, shots.num_shots):
        before = {int(g) for g in ids.before_ids[k - 1]}
        for i, g in enumerate(ids.global_ids[k]):
            g = int(g)
            if g not in before:
                continue  # a new identity, not a link
            links += 1
            if owner[g] != int(truth[k][i]):
                pair = {owner[g], int(truth[k][i])}
                if any(pair == set(p) for p in alike):
                    wrong_alike += 1
                else:
                    wrong += 1
    # people present on both sides of a cut that were not linked
    missed = 0
    for k in range(1, shots.num_shots):
        seen_before = {owner[int(g)] for g in ids.before_ids[k - 1]}
        for i, g in enumerate(ids.global_ids[k]):
            if int(g) not in {int(x) for x in ids.before_ids[k - 1]} and int(truth[k][i]) in seen_before:
                missed += 1
    return links, wrong, wrong_alike, missed


def _scene(name: str) -> tuple:
    import torch

    torch.set_num_threads(1)
    from multithumbs.body.model import load_body_model
    from multithumbs.perception import load_perception
    from multithumbs.perception.phalp_export import export_phalp
    from multithumbs.synth.files import write_video
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.scene import synthesize
    from multithumbs.synth.suite import suite_scene

    config = suite_scene("standard", name)
    body = load_body_model()
    video = synthesize(config, body)
    shots = video.truth.world.shots()
    simulated = simulate_perception(video, body)
    with tempfile.TemporaryDirectory() as tmp:
        path = write_video(Path(tmp) / "video.mp4", video.frames, config.fps)
        pkl = export_phalp(Path(tmp) / "results.pkl", simulated, shots, body)
        imported = load_perception(f"phalp:{pkl}", path, shots, trust=True)
    return (name, _links(imported, video, shots, body, config.dressed_alike),
            _links(simulated, video, shots, body, config.dressed_alike))


def main() -> None:
    from multithumbs.synth.suite import suite

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", nargs="+", default=[c.name for c in suite("standard")])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(_scene, args.scenes))
    print(f"{'scene':32s} | imported (pixels of the decoded video)    | simulated (rendered pixels)")
    print(f"{'':32s} | links  IDs  IDs-alike  missed            | links  IDs  IDs-alike  missed")
    totals = np.zeros((2, 4), int)
    for name, imp, sim in rows:
        totals += np.array([imp, sim])
        print(f"{name:32s} | {imp[0]:5d} {imp[1]:4d} {imp[2]:10d} {imp[3]:7d}            | "
              f"{sim[0]:5d} {sim[1]:4d} {sim[2]:10d} {sim[3]:7d}")
    print(f"{'total':32s} | {totals[0, 0]:5d} {totals[0, 1]:4d} {totals[0, 2]:10d} {totals[0, 3]:7d}            | "
          f"{totals[1, 0]:5d} {totals[1, 1]:4d} {totals[1, 2]:10d} {totals[1, 3]:7d}")


if __name__ == "__main__":
    main()
