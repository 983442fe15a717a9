#!/usr/bin/env bash
# Third-party reader check of the mission log: `grop demo` (debug build, simulated robot) writes
# an MCAP log, and the PyPI `mcap` package (not our reader) opens it, lists its channels and
# schemas, and decodes every message with nothing but `json`; every message of a channel in one
# of Foxglove's well-known schemas is parsed into that schema's protobuf message from the PyPI
# `foxglove-schemas-protobuf` package (.ci/mcap_check.py). The venv lives in target/mcap-venv
# and is reused. Exits non-zero on any failure.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
venv="$root/target/mcap-venv"
python="${PYTHON:-python3}"
pins=("mcap==1.6.0" "foxglove-schemas-protobuf==0.4.0" "protobuf==7.36.2")

if ! "$venv/bin/python" -c '
import importlib.metadata as m, sys
for pin in sys.argv[1:]:
    name, version = pin.split("==")
    assert m.version(name) == version, pin
import mcap, foxglove_schemas_protobuf, google.protobuf.json_format
' "${pins[@]}" 2>/dev/null; then
    echo "mcap-check: creating $venv with ${pins[*]}"
    rm -rf "$venv"
    "$python" -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check "${pins[@]}"
fi

# The feature set of `cargo test --workspace` (which CI runs first): nothing compiles again.
cargo build --quiet --workspace --bins --examples
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
RUST_LOG="${RUST_LOG:-warn}" "${CARGO_TARGET_DIR:-$root/target}/debug/grop" --log warn demo --no-build \
    --record "$work/demo.mcap" --run-dir "$work/run" --out "$work/demo.png" >"$work/demo.txt"
tail -n 3 "$work/demo.txt"
"$venv/bin/python" "$root/.ci/mcap_check.py" "$work/demo.mcap"
