"""Tasks that produce a video's per-shot inputs: shots, people, camera trajectories, shared spaces.

``simulate_inputs`` synthesises a scene and SIMULATES the inputs from its ground truth (the benchmark's
stand-ins for 4DHumans, DROID-SLAM and VGGT; labelled as simulated in every artifact and report).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from prefect import task
from prefect.cache_policies import NO_CACHE

from storage.codecs import encode
from storage.keys import artifact_key
from storage.store import ArtifactRef
from tasks.artifacts import STAGE_VERSIONS, open_store


@task(name="simulate_inputs", cache_policy=NO_CACHE, retries=1)
def simulate_inputs(store_url: str, scene: dict, out_dir: str | None = None) -> dict[str, Any]:
    """Synthesise a scene and its SIMULATED per-shot inputs; artifacts for truth, shots, tracks, cameras, spaces.

    Also writes the scene's files (video, ground truth, contact sheet) into ``out_dir`` when given.
    The scene is rendered only when one of its artifacts is missing.
    """
    from multithumbs.synth.scene import config_from_json

    config = config_from_json(scene)
    store = open_store(store_url)
    params = {"scene": scene}
    n_cuts = config.num_shots - 1
    names = ["truth", "shots", *(f"tracks_{k}" for k in range(config.num_shots)),
             *(f"trajectory_{k}" for k in range(config.num_shots)), *(f"space_{c}" for c in range(n_cuts))]
    keys = {n: artifact_key("simulate_inputs", STAGE_VERSIONS["simulate_inputs"], {**params, "part": n}, [])
            for n in names}
    want_files = out_dir is not None and not (Path(out_dir) / "video.mp4").exists()
    if not want_files and all(store.exists(k) for k in keys.values()):
        return {n: ArtifactRef(k, "simulate_inputs", store_url) for n, k in keys.items()}

    from multithumbs.body.model import load_body_model
    from multithumbs.synth.files import write_synthetic
    from multithumbs.synth.perception import simulate_perception
    from multithumbs.synth.scene import synthesize
    from multithumbs.synth.simulated_geometry import simulate_camera_trajectory, simulate_shared_space

    body = load_body_model()
    video = synthesize(config, body)
    if out_dir is not None:
        write_synthetic(out_dir, video)
    shots = video.truth.world.shots()
    tracks = simulate_perception(video, body)
    parts = {"truth": video.truth, "shots": shots,
             **{f"tracks_{k}": t for k, t in enumerate(tracks)},
             **{f"trajectory_{k}": simulate_camera_trajectory(video, k) for k in range(config.num_shots)},
             **{f"space_{c}": simulate_shared_space(video, c) for c in range(n_cuts)}}
    refs = {}
    for name, value in parts.items():
        arrays, attributes = encode(value)
        attributes["provenance"] = {"params": {**params, "part": name}, "simulated": True}
        refs[name] = store.write(keys[name], "simulate_inputs", arrays, attributes)
    return refs
