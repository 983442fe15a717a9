"""Train the Psi FCN on a `grop datagen` dataset and export it to ONNX for tract.

One command from a dataset folder to the committed model (docs/fcn.md, "Retraining"):

    .venv-train/bin/python models/training/train.py --data out/dataset --out models/psi-fcn.onnx

What it does:
1. loads dataset.npz (format of docs/architecture.md) and checks every array's dtype and shape;
2. splits by *scene* (validation scenes are never seen in training, as at deployment);
3. trains the FCN (psi_model.py) with a binary cross-entropy on the success fraction, masked to
   the labelled cells and weighted by trials per cell (the binomial likelihood of the trials);
4. keeps the epoch with the lowest validation mean squared error (the Brier score up to a constant);
5. exports ONNX (uint8 input [N,1,32,64] -> float32 heatmap [N,1,32,64], dynamic N), checks
   onnxruntime reproduces torch on the validation crops, and writes `<out>.json` with the
   settings, data summary, parameter count, MACs and validation metrics (for MODEL_CARD.md).

CPU only; torch is kept to --threads threads (default 2) because the machines are shared.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

sys.path.insert(0, str(Path(__file__).resolve().parent))
from psi_model import CROP_COLS, CROP_ROWS, PsiFcn, count_macs, count_parameters  # noqa: E402

REQUIRED = {
    "images": (np.uint8, 3),
    "labels": (np.float32, 3),
    "mask": (np.uint8, 3),
    "successes": (np.uint16, 3),
    "trials_per_cell": (np.uint16, 1),
    "scene": (np.int32, 1),
    "side": (np.int8, 1),
}


class DatasetError(Exception):
    pass


def load_dataset(folder: Path) -> dict[str, np.ndarray]:
    path = folder / "dataset.npz"
    if not path.is_file():
        raise DatasetError(f"{path}: no such file (run `grop datagen --out {folder}` first)")
    try:
        npz = np.load(path)
    except Exception as e:  # corrupt zip / not an npz
        raise DatasetError(f"{path}: cannot read as .npz: {e}") from e
    data = {}
    n = None
    for key, (dtype, ndim) in REQUIRED.items():
        if key not in npz:
            raise DatasetError(f"{path}: array '{key}' missing (have {sorted(npz.files)})")
        arr = npz[key]
        if arr.dtype != dtype or arr.ndim != ndim:
            raise DatasetError(f"{path}: array '{key}' is {arr.dtype} with {arr.ndim} dims, expected {np.dtype(dtype)} with {ndim}")
        if ndim == 3 and arr.shape[1:] != (CROP_ROWS, CROP_COLS):
            raise DatasetError(f"{path}: array '{key}' has crops of {arr.shape[1:]}, expected ({CROP_ROWS}, {CROP_COLS})")
        if n is None:
            n = arr.shape[0]
        elif arr.shape[0] != n:
            raise DatasetError(f"{path}: array '{key}' has {arr.shape[0]} tasks, 'images' has {n}")
        data[key] = arr
    if n == 0:
        raise DatasetError(f"{path}: empty dataset")
    if np.any(data["trials_per_cell"] == 0):
        raise DatasetError(f"{path}: a task has trials_per_cell == 0")
    return data


def split_by_scene(scene: np.ndarray, val_frac: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    ids = np.unique(scene)
    rng = np.random.default_rng(seed)
    rng.shuffle(ids)
    n_val = max(1, int(round(len(ids) * val_frac))) if len(ids) > 1 else 0
    val_ids = set(ids[:n_val].tolist())
    is_val = np.array([s in val_ids for s in scene])
    return np.flatnonzero(~is_val), np.flatnonzero(is_val)


def metrics(pred: np.ndarray, label: np.ndarray, mask: np.ndarray) -> dict[str, float]:
    m = mask.astype(bool)
    p, y = pred[m], label[m]
    bins = np.clip((p * 10).astype(int), 0, 9)
    ece = 0.0
    for b in range(10):
        sel = bins == b
        if sel.any():
            ece += sel.mean() * abs(p[sel].mean() - y[sel].mean())
    return {"mae": float(np.abs(p - y).mean()), "mse": float(((p - y) ** 2).mean()), "ece": float(ece)}


def predict(model: PsiFcn, images: np.ndarray, batch: int = 256) -> np.ndarray:
    out = []
    model.eval()
    with torch.no_grad():
        for i in range(0, len(images), batch):
            x = torch.from_numpy(images[i:i + batch]).unsqueeze(1)
            out.append(model(x).squeeze(1).numpy())
    return np.concatenate(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, required=True, help="folder written by `grop datagen`")
    ap.add_argument("--out", type=Path, default=Path("models/psi-fcn.onnx"))
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--lr", type=float, default=3e-3, help="Adam learning rate (cosine-decayed)")
    ap.add_argument("--weight-decay", type=float, default=1e-4)
    ap.add_argument("--val-frac", type=float, default=0.15, help="fraction of scenes held out")
    ap.add_argument("--hflip", action="store_true",
                    help="augment with left-right mirrored crops (valid only if the arm mount has no lateral offset)")
    ap.add_argument("--widths", type=str, default="8,16,32,8,1", help="c1,c2,c3,k,up1_kernel of psi_model.PsiFcn")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--max-minutes", type=float, default=15.0, help="stop training after this wall time")
    ap.add_argument("--opset", type=int, default=17)
    args = ap.parse_args()

    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    try:
        data = load_dataset(args.data)
    except DatasetError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    meta_in = {}
    if (args.data / "dataset.json").is_file():
        meta_in = json.loads((args.data / "dataset.json").read_text())

    images, labels, mask = data["images"], data["labels"], data["mask"]
    trials = data["trials_per_cell"].astype(np.float32)
    train_ix, val_ix = split_by_scene(data["scene"], args.val_frac, args.seed)
    print(f"{len(images)} tasks from {len(np.unique(data['scene']))} scenes: {len(train_ix)} train, {len(val_ix)} validation")
    mean = float(images[train_ix].mean())
    std = float(images[train_ix].std()) or 1.0
    c1, c2, c3, k, up1k = (int(v) for v in args.widths.split(","))
    model = PsiFcn(c1, c2, c3, k, up1k, pixel_mean=mean, pixel_std=std)
    n_params, macs = count_parameters(model), count_macs(model)
    print(f"model widths {args.widths}: {n_params} parameters, {macs} MACs per crop")

    x_tr = torch.from_numpy(images[train_ix]).unsqueeze(1)
    y_tr = torch.from_numpy(labels[train_ix]).unsqueeze(1)
    # Weight = trials per cell on labelled cells: BCE on the fraction times n is the binomial NLL.
    w_tr = torch.from_numpy(mask[train_ix].astype(np.float32) * trials[train_ix, None, None]).unsqueeze(1)
    if args.hflip:
        x_tr = torch.cat([x_tr, x_tr.flip(-1)])
        y_tr = torch.cat([y_tr, y_tr.flip(-1)])
        w_tr = torch.cat([w_tr, w_tr.flip(-1)])

    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=args.weight_decay)
    steps_per_epoch = math.ceil(len(x_tr) / args.batch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=args.lr, total_steps=args.epochs * steps_per_epoch,
                                                pct_start=0.1)
    best = (math.inf, None, -1)
    eval_ix = val_ix if len(val_ix) else train_ix
    start = time.time()
    epochs_run = 0
    for epoch in range(args.epochs):
        model.train()
        perm = torch.randperm(len(x_tr))
        total = 0.0
        for b in range(steps_per_epoch):
            sel = perm[b * args.batch:(b + 1) * args.batch]
            logits = model.logits(x_tr[sel])
            loss = (F.binary_cross_entropy_with_logits(logits, y_tr[sel], reduction="none") * w_tr[sel]).sum()
            loss = loss / w_tr[sel].sum().clamp(min=1.0)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += float(loss.detach())
        epochs_run = epoch + 1
        m = metrics(predict(model, images[eval_ix]), labels[eval_ix], mask[eval_ix])
        if m["mse"] < best[0]:
            best = (m["mse"], {kk: v.clone() for kk, v in model.state_dict().items()}, epoch)
        if epoch % 10 == 0 or epoch == args.epochs - 1:
            print(f"epoch {epoch:4d} loss {total / steps_per_epoch:.4f} val mae {m['mae']:.4f} "
                  f"mse {m['mse']:.4f} ece {m['ece']:.4f} ({time.time() - start:.0f} s)", flush=True)
        if time.time() - start > args.max_minutes * 60:
            print(f"time budget of {args.max_minutes} min reached after {epochs_run} epochs")
            break
    model.load_state_dict(best[1])
    model.eval()
    val_pred = predict(model, images[eval_ix])
    val_metrics = metrics(val_pred, labels[eval_ix], mask[eval_ix])
    train_metrics = metrics(predict(model, images[train_ix]), labels[train_ix], mask[train_ix])
    print(f"best epoch {best[2]}: validation {val_metrics}, train {train_metrics}")

    args.out.parent.mkdir(parents=True, exist_ok=True)
    dummy = torch.zeros(1, 1, CROP_ROWS, CROP_COLS, dtype=torch.uint8)
    torch.onnx.export(model, (dummy,), str(args.out), input_names=["crop"], output_names=["heatmap"],
                      dynamic_axes={"crop": {0: "batch"}, "heatmap": {0: "batch"}},
                      opset_version=args.opset, dynamo=False)
    import onnxruntime as ort

    sess = ort.InferenceSession(str(args.out), providers=["CPUExecutionProvider"])
    ort_pred = sess.run(None, {"crop": images[eval_ix][:, None]})[0][:, 0]
    max_diff = float(np.abs(ort_pred - val_pred).max())
    print(f"exported {args.out}; onnxruntime vs torch max |diff| = {max_diff:.2e}")
    if max_diff > 1e-4:
        print("error: exported model disagrees with torch", file=sys.stderr)
        return 1
    meta = {
        "model": args.out.name,
        # Checked by fcn-infer when it loads the model (FcnModel::load): the record must name the
        # bytes it describes.
        "sha256": hashlib.sha256(args.out.read_bytes()).hexdigest(),
        "architecture": "PsiFcn (models/training/psi_model.py), FCN-8s-style, strides 2/4/8, learned position biases",
        "widths_c1_c2_c3_k_up1kernel": [c1, c2, c3, k, up1k],
        "parameters": n_params,
        "macs_per_crop": macs,
        "flops_per_crop": 2 * macs,
        "input": "crop uint8 [N,1,32,64]",
        "output": "heatmap float32 [N,1,32,64] in [0,1]",
        "pixel_mean": mean,
        "pixel_std": std,
        "dataset": {"folder": str(args.data), "tasks": int(len(images)),
                    "scenes": int(len(np.unique(data["scene"]))),
                    "train_tasks": int(len(train_ix)), "validation_tasks": int(len(val_ix)),
                    "success_fraction": float((labels * mask).sum() / mask.sum()),
                    "generator": meta_in.get("generator", {})},
        "training": {"epochs_run": epochs_run, "best_epoch": best[2], "batch": args.batch, "lr": args.lr,
                     "optimizer": "AdamW + one-cycle cosine", "weight_decay": args.weight_decay,
                     "loss": "BCE on success fraction, masked, weighted by trials per cell",
                     "hflip": args.hflip, "seed": args.seed, "threads": args.threads,
                     "wall_s": round(time.time() - start, 1)},
        "validation": val_metrics,
        "train": train_metrics,
        "onnx_opset": args.opset,
        "onnxruntime_max_abs_diff": max_diff,
        "versions": {"torch": torch.__version__, "onnxruntime": ort.__version__, "numpy": np.__version__},
    }
    args.out.with_suffix(".json").write_text(json.dumps(meta, indent=2) + "\n")
    print(f"wrote {args.out.with_suffix('.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
