import shutil

from tasks.body import resolve_body, without_body
from tasks.method import method_params


def test_the_procedural_body_adds_nothing_to_the_keys(monkeypatch):
    monkeypatch.delenv("MULTITHUMBS_SMPL_MODEL", raising=False)
    assert resolve_body(None) == (None, {})
    assert method_params("full", None, {}) == method_params("full")


def test_a_user_file_is_keyed_by_its_bytes_in_the_stages_that_pose_bodies(tmp_path, monkeypatch):
    from multithumbs.body.procedural import procedural_model_path

    monkeypatch.delenv("MULTITHUMBS_SMPL_MODEL", raising=False)
    a, b = tmp_path / "a.npz", tmp_path / "moved" / "b.npz"
    shutil.copy(procedural_model_path(), a)
    b.parent.mkdir()
    shutil.copy(a, b)
    path, body = resolve_body(a)
    assert path == str(a.resolve()) and resolve_body(b)[1] == body  # same bytes elsewhere: same keys
    monkeypatch.setenv("MULTITHUMBS_SMPL_MODEL", str(b))
    assert resolve_body(None) == (str(b.resolve()), body)  # the environment variable is keyed too
    params = method_params("full", None, body)
    assert {s for s, p in params.items() if "body" in p} == {"align", "propagate", "post"}
    assert without_body(params["propagate"]) == method_params("full")["propagate"]
