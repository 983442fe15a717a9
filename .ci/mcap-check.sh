#!/usr/bin/env bash
# Third-party reader check of the mission log: `grop demo` (debug build, simulated robot) writes
# an MCAP log, and the PyPI `mcap` package (not our reader) opens it, lists its channels and
# schemas, and decodes every message with nothing but `json` (.ci/mcap_check.py). The venv lives
# in target/mcap-venv and is reused. Exits non-zero on any failure.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
venv="$root/target/mcap-venv"
python="${PYTHON:-python3}"

if ! "$venv/bin/python" -c "import mcap, importlib.metadata as m; assert m.version(\"mcap\") == \"1.6.0\"" 2>/dev/null; then
    echo "mcap-check: creating $venv with mcap==1.6.0"
    rm -rf "$venv"
    "$python" -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check "mcap==1.6.0"
fi

# The feature set of `cargo test --workspace` (which CI runs first): nothing compiles again.
cargo build --quiet --workspace --bins --examples
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
RUST_LOG="${RUST_LOG:-warn}" "$root/target/debug/grop" --log warn demo --no-build \
    --record "$work/demo.mcap" --run-dir "$work/run" --out "$work/demo.png" >"$work/demo.txt"
tail -n 3 "$work/demo.txt"
"$venv/bin/python" "$root/.ci/mcap_check.py" "$work/demo.mcap"
