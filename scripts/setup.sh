#!/usr/bin/env bash
# Create .venv and install Multi-THuMBS with its development tools, from the package registries only.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
[ -x .venv/bin/python ] || "$PY" -m venv .venv
PIP=(.venv/bin/python -m pip --disable-pip-version-check -q)
"${PIP[@]}" install --upgrade pip
# The CPU build of torch first: an unpinned torch pulls a multi-GB CUDA build.
"${PIP[@]}" install torch==2.13.0
"${PIP[@]}" install -e ".[dev]"
# scenedetect asks for opencv-python (GUI), which clobbers the headless cv2: install it alone.
"${PIP[@]}" install --no-deps scenedetect==0.7.2
# Depth-Anything-3 (a learned shared-space backend, tested on a tiny random model): its torchvision
# requirement does not import beside the CPU torch, and the adapter does not need it.
"${PIP[@]}" install --no-deps depth-anything-3==0.1.1
# TrackEval, the reference CLEAR-MOT evaluator the IDs tests compare with: it asks for opencv-python (GUI)
# too, and its CLEAR metric needs only numpy and scipy.
"${PIP[@]}" install --no-deps trackeval==1.3.0
