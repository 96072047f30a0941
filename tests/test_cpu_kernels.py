"""The CPU kernels pinned at import: what is set where, the tag keys hash, and that MKL and ATen really
take the pin when ``multithumbs`` is imported before torch computes (a fresh interpreter each)."""

import os
import subprocess
import sys

import pytest

from multithumbs.cpu_kernels import (OPENCV_PIN, OPENCV_TARGETS, PINNED_TAG, PINS, can_pin, cpu_flags, kernel_tag,
                                     network_kernel_tag, pin_cpu_kernels, pins_for)

AVX2 = frozenset({"sse4_2", "avx", "avx2", "fma"})


def test_pins_are_set_on_an_avx2_cpu_and_a_users_value_is_kept():
    environ = {"MKL_CBWR": "COMPATIBLE"}
    added = pin_cpu_kernels(environ, AVX2, "x86_64")
    assert environ["MKL_CBWR"] == "COMPATIBLE" and "MKL_CBWR" not in added
    assert {k: environ[k] for k in PINS if k != "MKL_CBWR"} == {k: v for k, v in PINS.items() if k != "MKL_CBWR"}
    assert "OPENCV_CPU_DISABLE" not in environ   # no AVX-512 here: OpenCV would warn


SKX = frozenset({"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"})


def test_opencv_is_pinned_only_where_avx512_exists():
    assert pins_for(AVX2 | SKX | {"avx512_vnni"}) == {**PINS, **OPENCV_PIN}
    assert pins_for(AVX2 | SKX) == {**PINS, "OPENCV_CPU_DISABLE": "AVX512-SKX"}  # no VNNI: CLX left alone
    assert pins_for(AVX2 | {"avx512f"}) == dict(PINS)
    assert pins_for(AVX2) == dict(PINS)


def test_opencv_knows_the_pins_names_and_stops_dispatching_to_them():
    # OpenCV itself is the judge: it writes "unknown CPU feature" for a name it does not have, and marks
    # a dispatched target it will not use with "?" in its features line
    env = {k: v for k, v in os.environ.items() if k != "OPENCV_CPU_DISABLE"}
    script = "import cv2; print(cv2.getCPUFeaturesLine())"
    free = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    pinned = subprocess.run([sys.executable, "-c", script], env={**env, **OPENCV_PIN}, capture_output=True,
                            text=True, check=True)
    assert "unknown CPU feature" not in pinned.stderr
    free_line, pinned_line = free.stdout.split(), pinned.stdout.split()
    dispatched = [name for name, _ in OPENCV_TARGETS if {f"*{name}", f"*{name}?"} & set(free_line)]
    assert "AVX512-SKX" in dispatched  # every wheel since 4.x ("?": not on this CPU); 5.x adds CLX
    assert all(f"*{name}?" in pinned_line for name in dispatched)


@pytest.mark.parametrize("flags, machine", [(frozenset({"sse4_2", "avx"}), "x86_64"), (AVX2, "aarch64"),
                                            (frozenset(), "x86_64")])
def test_nothing_is_forced_on_a_cpu_that_cannot_run_the_pinned_kernels(flags, machine):
    environ: dict[str, str] = {}
    assert not can_pin(flags, machine)
    assert pin_cpu_kernels(environ, flags, machine) == {} and environ == {}


@pytest.mark.skipif(not can_pin(cpu_flags(), os.uname().machine), reason="the pins need an AVX2 x86-64 CPU")
def test_the_tag_says_pinned_here_and_names_a_differing_switch():
    assert kernel_tag() == PINNED_TAG   # the test process imported multithumbs
    other = kernel_tag({**os.environ, "MKL_CBWR": "AUTO"})
    assert other.startswith("unpinned:") and "MKL_CBWR=AUTO" in other


def test_the_network_runtimes_instruction_set_is_named():
    assert network_kernel_tag(AVX2 | {"avx512f"}) == "avx512"
    assert network_kernel_tag(AVX2) == "avx2"
    assert network_kernel_tag(frozenset({"sse4_2"})) == "baseline"


def test_a_differing_kernel_tag_changes_every_key(monkeypatch):
    from storage.keys import artifact_key

    pinned = artifact_key("stage", 1, {"a": 1})
    monkeypatch.setenv("ATEN_CPU_CAPABILITY", "default")
    assert artifact_key("stage", 1, {"a": 1}) != pinned


PROBE = """
import hashlib, sys
if sys.argv[1] == "package":
    import multithumbs  # noqa: F401  (pins the kernels)
import torch
torch.set_num_threads(1)
g = torch.Generator().manual_seed(0)
a, b = torch.randn(16, 200, 200, generator=g), torch.randn(16, 200, 200, generator=g)
out = torch.bmm(a, b).numpy().tobytes() + torch.linalg.solve(a[:2] @ a[:2].mT + torch.eye(200), b[:2]).numpy().tobytes()
print(torch.backends.cpu.get_cpu_capability(), hashlib.sha256(out).hexdigest())
"""


def _probe(mode: str, **env: str) -> tuple[str, str]:
    clean = {k: v for k, v in os.environ.items() if k not in PINS and k not in OPENCV_PIN}
    done = subprocess.run([sys.executable, "-c", PROBE, mode], env={**clean, **env}, capture_output=True,
                          text=True, check=True)
    capability, digest = done.stdout.split()
    return capability, digest


@pytest.mark.skipif(not can_pin(cpu_flags(), os.uname().machine), reason="the pins need an AVX2 x86-64 CPU")
def test_importing_the_package_first_gives_the_bytes_of_the_pinned_libraries():
    pinned = _probe("torch", MKL_CBWR="AVX2", ATEN_CPU_CAPABILITY="avx2")
    assert _probe("package") == pinned
    assert pinned[0] == "AVX2"
    # The switch matters: MKL's bit-compatible baseline rounds otherwise (so this test can fail).
    assert _probe("torch", MKL_CBWR="COMPATIBLE", ATEN_CPU_CAPABILITY="avx2")[1] != pinned[1]
