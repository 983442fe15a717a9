#!/usr/bin/env bash
# From nothing to models/psi-fcn.onnx: a fresh dataset from the simulator, then training and
# ONNX export (1.5-10 minutes on 2 CPU cores; docs/fcn.md, "Retraining").
#
#   bash models/training/retrain.sh [robot.toml]
#
# Environment: the venv of models/training/requirements.txt at .venv-train (override with PYTHON).
set -euo pipefail
cd "$(dirname "$0")/../.."
PYTHON="${PYTHON:-.venv-train/bin/python}"
ROBOT_ARGS=()
if [[ $# -ge 1 ]]; then ROBOT_ARGS=(--robot "$1"); fi
cargo build --release -p grop-cli
# 200 environments x 10 targets x 192 cells x 5 trials = 1.92 M trials (~20 s).
target/release/grop datagen --out out/fcn-train --seed 1 --envs 200 --targets-per-env 10 \
    --trials-per-cell 5 --no-trials-csv "${ROBOT_ARGS[@]}"
# --hflip is valid because the default arm mount has no lateral offset; drop it otherwise.
"$PYTHON" models/training/train.py --data out/fcn-train --out models/psi-fcn.onnx \
    --epochs 30 --batch 32 --lr 3e-3 --hflip --threads 2 --seed 1
# Reference outputs for the tract-vs-onnxruntime agreement test.
"$PYTHON" models/training/make_golden.py --data out/fcn-train
# Quality against fresh ground truth (25 trials per cell) and the model card's thresholds.
target/release/grop model-eval --model models/psi-fcn.onnx --evaluators fcn,binary,blurred,oracle \
    --scenes 12 --targets 5 --trials 25 --json out/fcn-eval.json
