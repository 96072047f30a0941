"""Data roots generated once per test session (read-only for the tests; tests that break a root copy it)."""

from __future__ import annotations

import pytest

from tests.datasets.fixtures import make_ava, make_egobody, make_egohumans, make_sitcoms


@pytest.fixture(scope="session")
def egohumans(tmp_path_factory, body):
    root = tmp_path_factory.mktemp("egohumans")
    seq_dir, truth = make_egohumans(root, body)
    return root, seq_dir, truth


@pytest.fixture(scope="session")
def harmony4d(tmp_path_factory, body):
    root = tmp_path_factory.mktemp("harmony4d")
    seq_dir, truth = make_egohumans(root, body, dataset="harmony4d")
    return root, seq_dir, truth


@pytest.fixture(scope="session")
def egobody(tmp_path_factory, body):
    root = tmp_path_factory.mktemp("egobody")
    truth = make_egobody(root, body)
    return root, truth


@pytest.fixture(scope="session")
def bodies(body):
    """``gender -> body``: the procedural body stands in for the gendered SMPL models."""
    return lambda gender: body


@pytest.fixture(scope="session")
def ava(tmp_path_factory):
    root = tmp_path_factory.mktemp("ava")
    clip = make_ava(root)
    return root, clip


@pytest.fixture(scope="session")
def sitcoms(tmp_path_factory):
    root = tmp_path_factory.mktemp("sitcoms")
    return root, make_sitcoms(root)
