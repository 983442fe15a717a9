"""Reference outputs of the committed model from onnxruntime, for the tract agreement test
(models/fcn-infer/tests/load_and_predict.rs). Rerun after every retraining:

    python models/training/make_golden.py [--data out/fcn-train]

Writes tests/fixtures/golden_crops.bin (N x 2048 uint8) and golden_heatmaps.bin
(N x 2048 float32, little-endian): four dataset crops (or patterned crops without a dataset)
plus an empty-floor crop.
"""

import argparse
from pathlib import Path

import numpy as np
import onnxruntime as ort

MODELS = Path(__file__).resolve().parents[1]
FIX = MODELS / "fcn-infer" / "tests" / "fixtures"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", type=Path, default=MODELS.parent / "out" / "fcn-train")
    args = ap.parse_args()
    npz = args.data / "dataset.npz"
    if npz.is_file():
        crops = np.load(npz)["images"][[0, 7, 123, 999 % len(np.load(npz)["images"])]]
    else:
        crops = np.stack([(np.arange(2048).reshape(32, 64) * (k + 3) % 256).astype(np.uint8) for k in range(4)])
    crops = np.concatenate([crops, np.full((1, 32, 64), 96, np.uint8)])
    sess = ort.InferenceSession(str(MODELS / "psi-fcn.onnx"), providers=["CPUExecutionProvider"])
    heat = sess.run(None, {"crop": crops[:, None]})[0][:, 0].astype("<f4")
    crops.astype(np.uint8).tofile(FIX / "golden_crops.bin")
    heat.tofile(FIX / "golden_heatmaps.bin")
    print(f"wrote {len(crops)} golden crops/heatmaps to {FIX}")


if __name__ == "__main__":
    main()
