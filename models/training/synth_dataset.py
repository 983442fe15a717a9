"""Write a small synthetic dataset in the `grop datagen` format (docs/architecture.md).

It exists to test the training and export pipeline without the simulator: chairs are dark rotated
squares on a light floor, the table is the dark band along row 0, and a label is the Monte-Carlo
success fraction of a disc-shaped base (sigma 0.1 m noise) that must avoid the chairs and stand
inside a reach annulus around the target. It is NOT the robot's physics; real training uses
`grop datagen`.

    python models/training/synth_dataset.py --out /tmp/synth --tasks 64
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

ROWS, COLS = 32, 64
PX_M = 0.0625
CAND_ROWS = range(9, 17)
CAND_COLS = range(20, 44)


def cell_xy(target_x: float, r: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Near-crop cell centre in world coordinates (docs/architecture.md)."""
    return target_x - 2.0 + (c + 0.5) * PX_M, 6.0 - (r + 0.5) * PX_M


def render(target_x: float, chairs: np.ndarray) -> np.ndarray:
    rr, cc = np.meshgrid(np.arange(ROWS), np.arange(COLS), indexing="ij")
    x, y = cell_xy(target_x, rr, cc)
    img = np.full((ROWS, COLS), 235, np.uint8)
    img[y > 5.8] = 70  # table (y 5.8 .. 6.2)
    for cx, cy, yaw in chairs:
        dx, dy = x - cx, y - cy
        lx = np.cos(yaw) * dx + np.sin(yaw) * dy
        ly = -np.sin(yaw) * dx + np.cos(yaw) * dy
        img[(np.abs(lx) < 0.225) & (np.abs(ly) < 0.225)] = 120
    return img


def label(target_x: float, chairs: np.ndarray, trials: int, rng: np.random.Generator):
    succ = np.zeros((ROWS, COLS), np.uint16)
    for r in CAND_ROWS:
        for c in CAND_COLS:
            x, y = cell_xy(target_x, np.array(r), np.array(c))
            px = x + rng.normal(0.0, 0.1, trials)
            py = y + rng.normal(0.0, 0.1, trials)
            ok = np.hypot(px - target_x, py - 6.0) < 0.95
            ok &= py < 6.0 - 0.2 - 0.3 + 0.35  # base front must stay clear of the table
            for cx, cy, _ in chairs:
                ok &= np.hypot(px - cx, py - cy) > 0.3 + 0.25
            succ[r, c] = int(ok.sum())
    return succ


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--tasks", type=int, default=64)
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    n = args.tasks
    images = np.zeros((n, ROWS, COLS), np.uint8)
    successes = np.zeros((n, ROWS, COLS), np.uint16)
    mask = np.zeros((n, ROWS, COLS), np.uint8)
    mask[:, 9:17, 20:44] = 1
    targets = np.zeros((n, 3))
    scenes = np.zeros(n, np.int32)
    for i in range(n):
        scenes[i] = i // 4
        tx = rng.uniform(-6, 6)
        chairs = np.stack([rng.uniform(tx - 2, tx + 2, 4), rng.uniform(4.35, 5.35, 4),
                           rng.uniform(-np.pi, np.pi, 4)], axis=1)
        images[i] = render(tx, chairs)
        successes[i] = label(tx, chairs, args.trials, rng)
        targets[i] = (tx, 6.0, 1.3)
    labels = (successes / args.trials).astype(np.float32) * mask
    args.out.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(args.out / "dataset.npz", images=images, labels=labels, mask=mask,
                        successes=successes, trials_per_cell=np.full(n, args.trials, np.uint16),
                        targets=targets, scene=scenes, side=np.ones(n, np.int8))
    (args.out / "dataset.json").write_text(json.dumps({
        "format_version": 1, "generator": "models/training/synth_dataset.py (synthetic, not the simulator)",
        "seed": args.seed, "tasks": n, "trials_per_cell": args.trials}, indent=2))
    print(f"wrote {n} synthetic tasks to {args.out}")


if __name__ == "__main__":
    main()
