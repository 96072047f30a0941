"""Input and setup failures print one line naming the input, the problem and a log holding the traceback,
exit with 2 and write no outputs: before the flow (without importing Prefect or torch) and inside it."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

RUN_OUTPUTS = ("result.npz", "metrics.json", "overlay.mp4", "report.md", "outputs.json")


def cli(*args, tmp_path, prelude="", importtime=False):
    """Run the CLI in a fresh interpreter; ``prelude`` runs first (e.g. hides a module)."""
    code = f"import sys\n{prelude}\nsys.argv = ['multithumbs', *{[str(a) for a in args]!r}]\n" \
           "from multithumbs.cli import main\nmain()\n"
    env = dict(os.environ, MULTITHUMBS_CACHE=str(tmp_path / "cache"))
    flags = ["-X", "importtime"] if importtime else []
    return subprocess.run([sys.executable, *flags, "-c", code], capture_output=True, text=True, env=env, timeout=600)


def one_line(out) -> tuple[str, Path]:
    """The one error line (the import-time report aside) and the log file it names."""
    lines = [l for l in out.stderr.splitlines() if not l.startswith("import time:")]
    assert out.returncode == 2, out.stderr[-3000:]
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    log = re.search(r"\(details: (.+\.log)\)$", lines[0])
    assert log, lines[0]
    return lines[0], Path(log.group(1))


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """An 8-frame video with its perception file, and a 12-frame scene whose perception disagrees with it."""
    root = tmp_path_factory.mktemp("scenes")
    for name, frames in (("a", 8), ("b", 12)):
        done = subprocess.run([sys.executable, "-m", "multithumbs.cli", "synth", "--out", str(root / name), "--people",
                               "2", "--shots", "2", "--frames", str(frames), "--width", "320", "--height", "180"],
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
    return root


def test_refusals_before_the_flow_import_neither_prefect_nor_torch(tmp_path, scenes):
    video, pkl = scenes / "a" / "video.mp4", f"phalp:{scenes / 'a' / 'perception.pkl'}"
    cases = [
        (["run", tmp_path / "missing.mp4", "--out", tmp_path / "o", "--perception", pkl], "missing.mp4"),
        (["run", video, "--out", tmp_path / "o", "--perception", "hmr2"], "hmr2"),
        (["run", video, "--out", tmp_path / "o", "--perception", f"{pkl}+vitpose", "--trust-pickle",
          "--truth", tmp_path / "nope.npz"], "nope.npz"),
        (["run", video, "--out", tmp_path / "o", "--perception", pkl, "--trust-pickle", "--intrinsics", "0,1,2,3"],
         "--intrinsics"),
    ]
    for args, needle in cases:
        out = cli(*args, tmp_path=tmp_path, importtime=True)
        line, log = one_line(out)
        assert needle in line, (args, line)
        assert "Traceback" in log.read_text()
        imported = {l.split("|")[-1].strip() for l in out.stderr.splitlines() if l.startswith("import time:")}
        assert not imported & {"prefect", "torch"}, (args, sorted(imported & {"prefect", "torch"}))
    assert not (tmp_path / "o").exists()


def test_a_failure_inside_the_flow_is_one_line_and_writes_no_outputs(tmp_path, scenes):
    """The 12-frame scene's perception on the 8-frame video fails in the perception task, after the flow
    started: no Prefect traceback on the terminal, the traceback in the log, no outputs, no half-written
    artifacts."""
    out_dir = tmp_path / "o"
    out = cli("run", scenes / "a" / "video.mp4", "--out", out_dir, "--perception",
              f"phalp:{scenes / 'b' / 'perception.pkl'}", "--trust-pickle", tmp_path=tmp_path)
    line, log = one_line(out)
    assert "perception.pkl" in line and "beyond the end of the video" in line, line
    text = log.read_text()
    assert "Traceback" in text and "perception" in text
    assert "Task run" not in out.stderr
    assert not any((out_dir / name).exists() for name in RUN_OUTPUTS)
    store_tmp = out_dir / "store" / "tmp"
    assert not store_tmp.exists() or not any(store_tmp.iterdir())


@pytest.mark.parametrize("command", ["shots", "run"])
def test_a_package_only_setup_installs_is_named_with_its_install_command(tmp_path, scenes, command):
    """scenedetect comes from scripts/setup.sh only (it requires the GUI OpenCV): without it, one line."""
    video = scenes / "a" / "video.mp4"
    args = ["shots", video] if command == "shots" else \
        ["run", video, "--out", tmp_path / "o", "--perception", f"phalp:{scenes / 'a' / 'perception.pkl'}",
         "--trust-pickle"]
    # None in sys.modules makes `import scenedetect` raise ModuleNotFoundError, as when it is not installed.
    out = cli(*args, tmp_path=tmp_path, prelude="sys.modules['scenedetect'] = None")
    line, _ = one_line(out)
    assert "scenedetect" in line and "pip install --no-deps scenedetect==0.7.2" in line, line
    assert f"multithumbs {command}" in line
    assert not (tmp_path / "o").exists()


def test_an_unchecked_import_of_a_setup_only_package_is_one_line_too(tmp_path):
    """A missing setup-only module that no command checked for (here: imported by the prelude's own
    command) is still one line naming the install command, not a traceback."""
    prelude = ("sys.modules['scenedetect'] = None\n"
               "import multithumbs.cli as c\n"
               "@c.app.command('needs-scenedetect')\n"
               "def _n():\n    import scenedetect\n")
    out = cli("needs-scenedetect", tmp_path=tmp_path, prelude=prelude)
    line, _ = one_line(out)
    assert "pip install --no-deps scenedetect==0.7.2" in line


def test_missing_person_detector_files_are_one_line_before_the_flow(tmp_path, scenes):
    """The default perception needs NanoDet's files too: without them, one line naming them and the install
    command, before Prefect or torch is imported."""
    prelude = f"import os\nos.environ['MULTITHUMBS_NANODET_DIR'] = {str(tmp_path / 'none')!r}"
    out = cli("run", scenes / "a" / "video.mp4", "--out", tmp_path / "o", tmp_path=tmp_path, prelude=prelude,
              importtime=True)
    line, _ = one_line(out)
    assert "person detector 'nanodet'" in line and "nanodet.json" in line and "install with" in line, line
    imported = {l.split("|")[-1].strip() for l in out.stderr.splitlines() if l.startswith("import time:")}
    assert not imported & {"prefect", "torch"}
    assert not (tmp_path / "o").exists()
