"""tract vs onnxruntime on the same .onnx, same thread count (1), same core, in one run.

    .venv-train/bin/python models/bench/run_bench.py            # models/psi-fcn.onnx, writes docs/fcn.md
    .venv-train/bin/python models/bench/run_bench.py --model X.onnx --no-write --rounds 5

Builds the tract latency harness (models/fcn-infer/examples/latency.rs) and runs, round after
round, the three harnesses one after the other, each pinned to the same CPU core with `taskset`
when available: tract with our direct convolutions (`FcnModel`'s default), onnxruntime
(bench_ort.py), tract with its own convolutions (the reference). Each figure is the median over
the rounds of that round's p50 / p99, and each ratio the median of the per-round ratios, so a
burst of load on the shared machine moves one round, not the comparison. Writes the table between
the `<!-- bench:begin -->` / `<!-- bench:end -->` markers of docs/fcn.md.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import statistics
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
    ap.add_argument("--rounds", type=int, default=3, help="rounds of the three harnesses")
    ap.add_argument("--no-write", action="store_true", help="print the table only")
    args = ap.parse_args()

    subprocess.run(["cargo", "build", "--release", "-p", "fcn-infer", "--example", "latency"], cwd=ROOT, check=True)
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    tract_bin = (target if target.is_absolute() else ROOT / target) / "release" / "examples" / "latency"
    env = dict(os.environ, OMP_NUM_THREADS="1")

    def run_json(cmd: list[str]) -> dict:
        out = subprocess.run(pinned(cmd, args.core), cwd=ROOT, check=True, capture_output=True, text=True, env=env)
        return json.loads(out.stdout)

    rounds = []
    for _ in range(args.rounds):
        direct = run_json([str(tract_bin), str(args.model), str(args.iterations), "direct"])
        ort = run_json([sys.executable, str(ROOT / "models" / "bench" / "bench_ort.py"), str(args.model),
                        "--iterations", str(args.iterations), "--threads", "1"])
        reference = run_json([str(tract_bin), str(args.model), str(args.iterations), "tract"])
        rounds.append((direct, ort, reference))

    def med(values: list[float]) -> float:
        return statistics.median(values)

    rows = []
    for b in ("batch1", "batch6"):
        d = lambda k: med([r[0][b][k] for r in rounds])  # noqa: E731
        o = lambda k: med([r[1][b][k] for r in rounds])  # noqa: E731
        t = lambda k: med([r[2][b][k] for r in rounds])  # noqa: E731
        wall = med([r[0][b]["p50_us"] / r[1][b]["p50_us"] for r in rounds])
        net = med([r[0][b]["p50_us"] / max(r[1][b]["net_p50_us"], 1e-9) for r in rounds])
        gain = med([r[2][b]["p50_us"] / r[0][b]["p50_us"] for r in rounds])
        rows.append(f"| {b[5:]} | {d('p50_us'):.1f} | {d('p99_us'):.1f} | {o('p50_us'):.1f} | {o('p99_us'):.1f} | "
                    f"{o('net_p50_us'):.1f} | {t('p50_us'):.1f} | {t('p99_us'):.1f} | {wall:.2f} | {net:.2f} | {gain:.2f} |")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    ort_version = rounds[0][1]["version"]
    model_name = args.model.relative_to(ROOT) if args.model.is_relative_to(ROOT) else args.model
    table = "\n".join([
        f"Measured {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC on {cpu_name()}, one thread, all pinned to "
        f"core {args.core}, {args.rounds} rounds of {args.iterations} calls each (batch 6: half), load average {load:.1f} at "
        f"the end; onnxruntime {ort_version}. Model `{model_name}`. Medians over the rounds.",
        "",
        "| crops per call | tract, direct conv p50 (us) | p99 (us) | ORT p50 (us) | ORT p99 (us) | ORT net p50 (us) "
        "| tract, own conv p50 (us) | p99 (us) | direct / ORT (wall) | direct / ORT (net) | own conv / direct |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"Model load + optimisation: tract with direct conv {med([r[0]['load_ms'] for r in rounds]):.0f} ms (plans for "
        f"batches 1 to 6), with its own {med([r[2]['load_ms'] for r in rounds]):.0f} ms, onnxruntime "
        f"{med([r[1]['load_ms'] for r in rounds]):.0f} ms.",
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
