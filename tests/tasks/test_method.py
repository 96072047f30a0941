"""Stage parameters: each stage's key hashes only what it reads."""

import pytest

from multithumbs.errors import InputError
from tasks.method import method_config, method_params


def test_a_reid_override_changes_only_reid_params():
    base, changed = method_params("full"), method_params("full", {"reid": {"max_distance": 0.8}})
    assert [s for s in base if base[s] != changed[s]] == ["reid"]
    assert method_config("full", {"reid": {"max_distance": 0.8}}).reid.max_distance == 0.8


def test_variants_share_alignment_params_where_the_method_does():
    assert method_params("full")["align"] == method_params("no_post")["align"] == method_params("distance_only")["align"]
    assert method_params("full")["align"] != method_params("no_cam")["align"]


@pytest.mark.parametrize("overrides,needle", [({"reid": {"nope": 1}}, "reid.nope"), ({"bogus": 1}, "bogus")])
def test_unknown_overrides_are_named(overrides, needle):
    with pytest.raises(InputError, match=needle):
        method_config("full", overrides)
