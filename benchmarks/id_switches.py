"""Every identity switch of chosen standard-suite scenes and variants, with what the frames show there.

Runs the scenes as ``multithumbs bench`` does (SIMULATED perception, shared space and camera tracking;
with ``--from-pixels``, every input from the rendered video as ``bench --from-pixels`` computes it, read
from its store under ``MULTITHUMBS_CACHE/bench_store`` when an earlier bench kept it), evaluates each
variant, and prints one line per CLEAR-MOT switch: the frame, the true person, the predicted ids before
and after with the ``shot:local track`` each was at the switch's shot, the frame it was last matched,
the cut the gap spans (-1: within a shot), the IoU of the true person's box with the old and the new
id's box at the switch frame, and the largest IoU of that true person's box with another true person's
(people overlapping in the image).

    .venv/bin/python benchmarks/id_switches.py --scenes s08_dressed_alike,s12_alike_crossing_25deg \\
        --variants full,appearance_only
    .venv/bin/python benchmarks/id_switches.py --scenes s07_crossing_at_cut --from-pixels
"""

from __future__ import annotations

import argparse

import multithumbs  # noqa: F401  (before numpy and torch: it pins the CPU kernels, multithumbs/cpu_kernels.py)
import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", required=True, help="comma-separated standard-suite scene names")
    parser.add_argument("--variants", default="full", help="comma-separated variants")
    parser.add_argument("--from-pixels", action="store_true",
                        help="every input from the rendered video, as `multithumbs bench --from-pixels`")
    args = parser.parse_args()

    import torch

    from multithumbs.bench import run_scene_results
    from multithumbs.body.model import load_body_model
    from multithumbs.geometry import world_to_camera
    from multithumbs.metrics.evaluate import body_points, evaluate
    from multithumbs.metrics.identity import box_iou, projected_boxes
    from multithumbs.synth.commands import pixel_input_cache
    from multithumbs.synth.suite import suite_scene

    torch.set_num_threads(1)
    body = load_body_model()
    variants = args.variants.split(",")
    for name in args.scenes.split(","):
        pixels = {"inputs": "pixels", "input_cache": pixel_input_cache()} if args.from_pixels else {}
        truth, results = run_scene_results(suite_scene("standard", name), variants, body, **pixels)
        _, true_vertices = body_points(body, truth.world)
        true_boxes, _ = projected_boxes(world_to_camera(true_vertices, truth.world.R, truth.world.t),
                                        truth.world.K, truth.world.image_size)
        for variant, result in results.items():
            report = evaluate(result, truth, body)
            _, vertices = body_points(body, result)
            boxes, _ = projected_boxes(world_to_camera(vertices, result.R, result.t), result.K, result.image_size)
            row = {int(g): p for p, g in enumerate(result.person_ids)}
            shot_of = np.searchsorted(result.cut_frames, np.arange(len(result.R)), side="right")

            def tracks_of(pid: int, t: int) -> str:
                """The ``shot:local`` tracks global id ``pid`` has in the shot of frame ``t``."""
                k = int(shot_of[t])
                local = [int(m[1]) for m in result.id_map if int(m[0]) == k and int(m[2]) == pid]
                return ",".join(f"{k}:{i}" for i in local) or f"{k}:-"
            events = report["id_switch_events"][0]
            print(f"{name} {variant}: {len(events)} switches, cuts {truth.world.cut_frames.tolist()}")
            for e in events:
                t, g = e["frame"], e["true_person"]
                iou = lambda pid: float(box_iou(true_boxes[g, t][None], boxes[row[pid], t][None])[0, 0])
                others = [q for q in range(len(true_boxes)) if q != g and truth.visible[q, t]]
                crowd = max((float(box_iou(true_boxes[g, t][None], true_boxes[q, t][None])[0, 0]) for q in others),
                            default=0.0)
                print(f"  frame {t:4d} true {g}: id {e['from_id']} ({tracks_of(e['from_id'], t)}) -> {e['to_id']} "
                      f"({tracks_of(e['to_id'], t)}) (last matched {e['last_matched']}, "
                      f"cut {e['cut']}); IoU old {iou(e['from_id']):.2f} new {iou(e['to_id']):.2f}; "
                      f"max IoU with another true person {crowd:.2f}")


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
