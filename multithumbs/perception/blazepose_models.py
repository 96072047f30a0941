"""BlazePose's model files: where they live, how they get there, and the loaded pair.

The two files are taken out of MediaPipe's official wheel (``mediapipe==0.10.21``, Apache-2.0) by
``scripts/setup.sh``, which runs ``python -m multithumbs.perception.blazepose_models install``: pip
downloads the wheel (without its dependencies, which do not fit the project's numpy 2), the two members
below are extracted and their SHA-256 checked. Nothing is downloaded at run time.

Folder: ``$MULTITHUMBS_BLAZEPOSE_DIR`` when set, else ``<venv>/share/multithumbs/blazepose``.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from multithumbs.errors import InputError
from multithumbs.perception import blazepose as bp
from multithumbs.perception.packaged_models import (PackagedModel, check_files, missing_files, model_folder,
                                                    write_files)

MEDIAPIPE_WHEEL = "mediapipe==0.10.21"
MODEL = PackagedModel(
    label="perception backend 'blazepose'", env_var="MULTITHUMBS_BLAZEPOSE_DIR", folder_name="blazepose",
    files={"pose_detection.tflite": ("mediapipe/modules/pose_detection/pose_detection.tflite",
                                     "9ba9dd3d42efaaba86b4ff0122b06f29c4122e756b329d89dca1e297fd8f866c"),
           "pose_landmark_full.tflite": ("mediapipe/modules/pose_landmark/pose_landmark_full.tflite",
                                         "e9a5c5cb17f736fafd4c2ec1da3b3d331d6edbe8a0d32395855aeb2cdfd64b9f")},
    install_command="python -m multithumbs.perception.blazepose_models install (scripts/setup.sh runs it)")
MODEL_FILES = MODEL.files
"""File name -> (member of the wheel, SHA-256)."""
INSTALL_COMMAND = MODEL.install_command


def model_dir() -> Path:
    """The folder holding the two model files (module docstring)."""
    return model_folder(MODEL)


def missing_models(folder: Path | None = None) -> list[str]:
    """Names of the model files absent from ``folder`` (default :func:`model_dir`) or not the expected bytes."""
    return missing_files(MODEL, folder)


def check_models(folder: Path | None = None) -> Path:
    """The model folder, or :class:`InputError` naming what is missing and the command that installs it."""
    folder = check_files(MODEL, folder)
    try:
        import ai_edge_litert.interpreter  # noqa: F401
    except ImportError as exc:
        raise InputError("perception backend 'blazepose': the ai-edge-litert package is not installed; "
                         "pip install ai-edge-litert==2.3.0") from exc
    return folder


def install_models(folder: Path | None = None, wheel: Path | None = None) -> Path:
    """Extract the two files from MediaPipe's wheel (downloaded by pip unless ``wheel`` is given) into
    ``folder``; existing files with the right digest are kept. Writes through a temporary name, so an
    interrupted install leaves nothing half-written."""
    folder = folder or model_dir()
    if not missing_models(folder):
        return folder
    with tempfile.TemporaryDirectory() as tmp:
        if wheel is None:
            subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "--quiet", "--disable-pip-version-check",
                            MEDIAPIPE_WHEEL, "-d", tmp], check=True)
            wheel = next(Path(tmp).glob("mediapipe-*.whl"))
        with zipfile.ZipFile(wheel) as archive:
            write_files(MODEL, folder, archive.read, str(wheel))
    return folder


@contextlib.contextmanager
def _native_stderr_kept_back():
    """The runtime's C++ logging writes "INFO: Created TensorFlow Lite XNNPACK delegate" straight to file
    descriptor 2 on every load, which no Python setting silences: hold it back, and let it through only when
    loading fails (then it may say why)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as held:
        os.dup2(held.fileno(), 2)
        try:
            yield
        except BaseException:
            os.dup2(saved, 2)
            held.seek(0)
            sys.stderr.write(held.read().decode(errors="replace"))
            raise
        finally:
            os.dup2(saved, 2)
            os.close(saved)


class BlazePose:
    """The loaded detector and landmark model (``ai_edge_litert`` interpreters, ``num_threads`` each).

    ``detect(image)`` gives :class:`~multithumbs.perception.blazepose.Detection` s best first;
    ``landmarks(image, roi)`` gives :class:`~multithumbs.perception.blazepose.Landmarks`. Images are
    ``(H, W, 3)`` uint8 RGB.
    """

    def __init__(self, folder: Path | None = None, num_threads: int = 2):
        from ai_edge_litert.interpreter import Interpreter

        folder = check_models(folder)
        with _native_stderr_kept_back():
            self._detector = Interpreter(model_path=str(folder / "pose_detection.tflite"), num_threads=num_threads)
            self._landmarker = Interpreter(model_path=str(folder / "pose_landmark_full.tflite"),
                                           num_threads=num_threads)
            for interpreter in (self._detector, self._landmarker):
                interpreter.allocate_tensors()

    @staticmethod
    def _run(interpreter, tensor: np.ndarray) -> dict[str, np.ndarray]:
        interpreter.set_tensor(interpreter.get_input_details()[0]["index"], np.ascontiguousarray(tensor))
        interpreter.invoke()
        return {d["name"]: interpreter.get_tensor(d["index"]).copy() for d in interpreter.get_output_details()}

    def detect(self, image: np.ndarray, min_score: float = bp.MIN_DETECTION_SCORE) -> list[bp.Detection]:
        tensor, scale, offset = bp.letterbox(image)
        out = self._run(self._detector, tensor)
        return bp.decode_detections(out["Identity"][0], out["Identity_1"][0, :, 0], scale, offset, min_score)

    def landmarks(self, image: np.ndarray, roi: bp.Roi) -> bp.Landmarks:
        return bp.decode_landmarks(self._run(self._landmarker, bp.crop(image, roi)), roi, image.shape[:2])


def _main(argv: list[str]) -> int:
    if argv[:1] != ["install"]:
        print("usage: python -m multithumbs.perception.blazepose_models install [WHEEL]", file=sys.stderr)
        return 2
    try:
        folder = install_models(wheel=Path(argv[1]) if len(argv) > 1 else None)
    except (InputError, subprocess.CalledProcessError, OSError, KeyError, StopIteration) as exc:
        print(f"BlazePose models: {exc}", file=sys.stderr)
        return 1
    print(f"BlazePose models in {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
