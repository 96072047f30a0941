"""Speed of the 4DHumans/PHALP results path on one standard scene: export, import, appearance from pixels.

Prints the median over ``--repeats`` runs of each step (the machine is noisy), plus the file size.

Usage: python benchmarks/perception_import.py [--scene s03_four_people_45deg] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", default="s03_four_people_45deg")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    from multithumbs.body.model import load_body_model
    from multithumbs.perception.appearance import fill_appearance
    from multithumbs.perception.phalp import load_phalp
    from multithumbs.perception.phalp_export import export_phalp
    from multithumbs.synth.files import write_video
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.scene import synthesize
    from multithumbs.synth.suite import suite_scene

    config = suite_scene("standard", args.scene)
    body = load_body_model()
    video = synthesize(config, body)
    shots = video.truth.world.shots()
    tracks = simulate_perception(video, body)
    detections = sum(int(tr.valid.sum()) for tr in tracks)
    times: dict[str, list[float]] = {"export": [], "import": [], "appearance (decode + describe)": []}
    with tempfile.TemporaryDirectory() as tmp:
        mp4 = write_video(Path(tmp) / "video.mp4", video.frames, config.fps)
        for r in range(args.repeats):
            pkl = Path(tmp) / f"results{r}.pkl"
            start = time.perf_counter()
            export_phalp(pkl, tracks, shots, body)
            times["export"].append(time.perf_counter() - start)
            start = time.perf_counter()
            imported = load_phalp(pkl, shots, config.image_size, trust=True)
            times["import"].append(time.perf_counter() - start)
            start = time.perf_counter()
            fill_appearance(imported.tracks, mp4)
            times["appearance (decode + describe)"].append(time.perf_counter() - start)
        size = pkl.stat().st_size
    print(f"{args.scene}: {config.num_frames} frames {config.image_size[1]}x{config.image_size[0]}, "
          f"{detections} detections, results file {size / 1e6:.2f} MB")
    for name, values in times.items():
        median = statistics.median(values)
        print(f"{name:32s} median {median:.3f} s ({1000 * median / detections:.2f} ms per detection) "
              f"over {len(values)} runs")


if __name__ == "__main__":
    main()
