"""onnxruntime latency on the same .onnx and thread count as the tract harness.

    python models/bench/bench_ort.py models/psi-fcn.onnx --iterations 2000 --threads 1

Prints one JSON object (microseconds). Python's own per-call cost (binding, numpy conversion,
output allocation) is measured separately by timing a trivial model with the same input and
output tensors (crop -> crop / 255, fixture scale.onnx), so that `net = wall - overhead` estimates
what onnxruntime itself spends on the network.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import onnxruntime as ort

TRIVIAL = Path(__file__).resolve().parents[1] / "fcn-infer" / "tests" / "fixtures" / "scale.onnx"


def session(path: Path, threads: int) -> ort.InferenceSession:
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = threads
    opts.inter_op_num_threads = 1
    opts.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    return ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])


def measure(sess: ort.InferenceSession, x: np.ndarray, iters: int) -> dict[str, float]:
    feed = {"crop": x}
    for _ in range(iters // 10 + 10):
        sess.run(None, feed)
    us = np.empty(iters)
    for i in range(iters):
        t = time.perf_counter_ns()
        sess.run(None, feed)
        us[i] = (time.perf_counter_ns() - t) / 1e3
    return {"p50_us": float(np.percentile(us, 50)), "p99_us": float(np.percentile(us, 99)), "mean_us": float(us.mean())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model", type=Path)
    ap.add_argument("--iterations", type=int, default=2000)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    crops = {b: rng.integers(0, 256, (b, 1, 32, 64), dtype=np.uint8) for b in (1, 6)}
    t = time.perf_counter()
    model = session(args.model, args.threads)
    load_ms = (time.perf_counter() - t) * 1e3
    trivial = session(TRIVIAL, args.threads)
    out = {"runtime": "onnxruntime", "version": ort.__version__, "threads": args.threads,
           "iterations": args.iterations, "load_ms": round(load_ms, 1)}
    for b in (1, 6):
        iters = args.iterations if b == 1 else args.iterations // 2
        wall = measure(model, crops[b], iters)
        overhead = measure(trivial, crops[b], iters)
        wall["overhead_p50_us"] = overhead["p50_us"]
        wall["net_p50_us"] = wall["p50_us"] - overhead["p50_us"]
        out[f"batch{b}"] = wall
    print(json.dumps(out))


if __name__ == "__main__":
    main()
