import json

import pytest

from multithumbs.datasets.clip_specs import ClipSpec, load_spec, load_specs, spec_from_dict
from multithumbs.errors import InputError

SEQ = "01_tagging/001_tagging"
SPEC = dict(name="eh_cut3", dataset="egohumans", sequence=SEQ, cameras=["cam01", "cam02"], cuts=[3], num_frames=6)


def test_spec_files_json_and_toml_agree(tmp_path):
    (tmp_path / "a.json").write_text(json.dumps(SPEC))
    (tmp_path / "b.toml").write_text('name = "eh_cut3"\ndataset = "egohumans"\nsequence = "01_tagging/001_tagging"\n'
                                     'cameras = ["cam01", "cam02"]\ncuts = [3]\nnum_frames = 6\n')
    assert load_spec(tmp_path / "a.json") == load_spec(tmp_path / "b.toml") == ClipSpec(**SPEC)
    (tmp_path / "list.json").write_text(json.dumps([SPEC, dict(SPEC, name="other", cuts=[2])]))
    assert [s.name for s in load_specs([tmp_path / "list.json"])] == ["eh_cut3", "other"]
    with pytest.raises(InputError, match="two specs are named 'eh_cut3'"):
        load_specs([tmp_path / "a.json", tmp_path / "b.toml"])


@pytest.mark.parametrize("change,needle", [
    (dict(cameras=["cam01"]), "1 cameras for 2 shots"),
    (dict(cuts=[6]), "cuts must increase strictly inside"),
    (dict(cuts=[0]), "cuts must increase strictly inside"),
    (dict(dataset="kitti"), "dataset must be one of"),
    (dict(name="../up"), "names a folder"),
    (dict(stride=0), "stride >= 1"),
    (dict(image_size=[4, 4]), "image_size"),
    (dict(fps=-1), "fps must be a positive"),
    (dict(extra=1), "unknown field 'extra'"),
    (dict(cuts=[1.5]), "expected an integer"),
    (dict(level="yes"), "level must be true or false"),
])
def test_bad_specs_are_one_line_errors(change, needle):
    with pytest.raises(InputError, match=needle) as info:
        spec_from_dict(dict(SPEC, **change), "spec.json")
    assert "\n" not in str(info.value)


def test_missing_spec_fields_and_files(tmp_path):
    with pytest.raises(InputError, match="missing field 'cuts'"):
        spec_from_dict({k: v for k, v in SPEC.items() if k != "cuts"}, "s.json")
    with pytest.raises(InputError, match="no such spec file"):
        load_spec(tmp_path / "nope.toml")
    (tmp_path / "bad.toml").write_text("name = ")
    with pytest.raises(InputError, match="bad.toml: not valid TOML"):
        load_spec(tmp_path / "bad.toml")
