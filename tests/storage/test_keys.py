import dataclasses

import numpy as np
import pytest

from multithumbs.method.reid import ReidConfig
from storage.keys import artifact_key, canonical_json, file_digest, is_key


def test_canonical_json_is_order_and_spelling_independent():
    assert canonical_json({"b": 1, "a": [1.0, 2]}) == canonical_json({"a": (1.0, 2), "b": 1})
    assert canonical_json(np.float32(0.5)) == canonical_json(0.5)
    assert canonical_json(-0.0) == canonical_json(0.0)
    assert canonical_json(float("inf")) != canonical_json(1e308)
    with pytest.raises(TypeError, match="cannot key"):
        canonical_json(object())


def test_keys_chain_like_a_merkle_dag():
    reid = ReidConfig()
    up = artifact_key("align", 1, {"iterations": [500, 500, 1500]}, ["video-key"])
    down = artifact_key("reid", 1, reid, [up])
    assert is_key(up) and is_key(down)
    # A re-ID parameter changes re-ID's key only; an upstream change moves both.
    assert artifact_key("reid", 1, dataclasses.replace(reid, max_distance=0.8), [up]) != down
    assert artifact_key("align", 1, {"iterations": [500, 500, 1500]}, ["video-key"]) == up
    up2 = artifact_key("align", 1, {"iterations": [500, 500, 1000]}, ["video-key"])
    assert up2 != up and artifact_key("reid", 1, reid, [up2]) != down
    assert artifact_key("reid", 2, reid, [up]) != down  # a new stage version too
    assert artifact_key("reid", 1, reid, [up], package_version="9.9") != down


def test_file_digest_streams_the_bytes(tmp_path):
    path = tmp_path / "v.bin"
    path.write_bytes(b"x" * 3_000_001)
    import hashlib
    assert file_digest(path, chunk_size=1000) == hashlib.sha256(b"x" * 3_000_001).hexdigest()
