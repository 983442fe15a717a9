"""tract vs onnxruntime on the same .onnx, same thread count (1), same core, in one run.

    .venv-train/bin/python models/bench/run_bench.py            # models/psi-fcn.onnx, writes docs/fcn.md
    .venv-train/bin/python models/bench/run_bench.py --model X.onnx --no-write

Builds and runs the tract latency harness (models/fcn-infer/examples/latency.rs) and the
onnxruntime harness (bench_ort.py) one after the other, each pinned to the same CPU core with
`taskset` when available, and writes the side-by-side table (p50, p99, ratio) between the
`<!-- bench:begin -->` / `<!-- bench:end -->` markers of docs/fcn.md.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BEGIN, END = "<!-- bench:begin -->", "<!-- bench:end -->"


def pinned(cmd: list[str], core: int) -> list[str]:
    return (["taskset", "-c", str(core)] + cmd) if shutil.which("taskset") else cmd


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", type=Path, default=ROOT / "models" / "psi-fcn.onnx")
    ap.add_argument("--iterations", type=int, default=5000)
    ap.add_argument("--core", type=int, default=0, help="CPU core both harnesses are pinned to")
    ap.add_argument("--no-write", action="store_true", help="print the table only")
    args = ap.parse_args()

    subprocess.run(["cargo", "build", "--release", "-p", "fcn-infer", "--example", "latency"], cwd=ROOT, check=True)
    tract_bin = ROOT / "target" / "release" / "examples" / "latency"
    env = dict(os.environ, OMP_NUM_THREADS="1")
    tract = json.loads(subprocess.run(pinned([str(tract_bin), str(args.model), str(args.iterations)], args.core),
                                      cwd=ROOT, check=True, capture_output=True, text=True, env=env).stdout)
    ort = json.loads(subprocess.run(pinned([sys.executable, str(ROOT / "models" / "bench" / "bench_ort.py"), str(args.model),
                                            "--iterations", str(args.iterations), "--threads", "1"], args.core),
                                    cwd=ROOT, check=True, capture_output=True, text=True, env=env).stdout)

    rows = []
    for b in ("batch1", "batch6"):
        t, o = tract[b], ort[b]
        rows.append(f"| {b[5:]} | {t['p50_us']:.1f} | {t['p99_us']:.1f} | {o['p50_us']:.1f} | {o['p99_us']:.1f} | "
                    f"{o['overhead_p50_us']:.1f} | {o['net_p50_us']:.1f} | {t['p50_us'] / o['p50_us']:.2f} | "
                    f"{t['p50_us'] / max(o['net_p50_us'], 1e-9):.2f} |")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    table = "\n".join([
        f"Measured {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC on {cpu_name()}, one thread, both pinned to "
        f"core {args.core}, {args.iterations} calls each (batch 6: half), load average {load:.1f} at the end; "
        f"onnxruntime {ort['version']}. Model `{args.model.relative_to(ROOT) if args.model.is_relative_to(ROOT) else args.model}`.",
        "",
        "| crops per call | tract p50 (us) | tract p99 (us) | ORT p50 (us) | ORT p99 (us) | ORT Python overhead p50 (us) "
        "| ORT net p50 (us) | tract / ORT (wall) | tract / ORT (net) |",
        "|---|---|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"Model load + optimisation: tract {tract['load_ms']:.0f} ms, onnxruntime {ort['load_ms']:.0f} ms.",
    ])
    print(table)
    if not args.no_write:
        doc = ROOT / "docs" / "fcn.md"
        text = doc.read_text()
        if BEGIN not in text or END not in text:
            print(f"error: {doc} lacks the {BEGIN} / {END} markers", file=sys.stderr)
            return 1
        head, rest = text.split(BEGIN, 1)
        _, tail = rest.split(END, 1)
        doc.write_text(f"{head}{BEGIN}\n{table}\n{END}{tail}")
        print(f"wrote the table into {doc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
