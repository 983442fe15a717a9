#!/usr/bin/env bash
# Third-party decoder check of the VLP-16 driver (docs/lidar.md): the simulated sensor
# (`cargo run -p vlp16 --example sim_pcap`) writes two revolutions of data packets as a pcap file
# and our decoding of them as CSV; the PyPI `velodyne-decoder` package (not our decoder) decodes
# the pcap, and .ci/vlp16_decoder_check.py checks the same point count and every point within
# 1 mm and 0.01 degree. The venv lives in target/vlp16-venv and is reused. Closing line:
# `N passed, N failed`; exits non-zero on any failure.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
venv="$root/target/vlp16-venv"
python="${PYTHON:-python3}"

if ! "$venv/bin/python" -c "import velodyne_decoder, importlib.metadata as m; assert m.version(\"velodyne-decoder\") == \"3.1.0\"" 2>/dev/null; then
    echo "vlp16-decoder-check: creating $venv with velodyne-decoder==3.1.0"
    rm -rf "$venv"
    "$python" -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check "velodyne-decoder==3.1.0"
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
# Built with the feature set of `cargo test --workspace` (which CI runs first): nothing compiles
# again (`cargo run -p vlp16` alone would build its dependencies with other features).
cargo build --quiet --workspace --bins --examples
"${CARGO_TARGET_DIR:-$root/target}/debug/examples/sim_pcap" "$work" </dev/null
"$venv/bin/python" "$root/.ci/vlp16_decoder_check.py" "$work/sim.pcap" "$work/points.csv"
