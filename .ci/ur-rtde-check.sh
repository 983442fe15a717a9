#!/usr/bin/env bash
# Third-party client check: the PyPI `ur-rtde` 1.6.5 package (RTDEReceiveInterface and
# DashboardClient) against the simulated UR5e (`sim-ur5e`).
#
# ur_rtde's RTDEReceiveInterface takes no port argument, so the simulator's RTDE server must be
# on the default port 30004; every other port is chosen by the OS and passed to the test in a
# JSON file. The venv lives in target/ur-rtde-venv and is reused. Closing line of the Python test:
# `N passed, N failed`; the script exits non-zero on any failure.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
venv="$root/target/ur-rtde-venv"
python="${PYTHON:-python3}"

if ! "$venv/bin/python" -c "import rtde_receive, dashboard_client" 2>/dev/null; then
    echo "ur-rtde-check: creating $venv with ur-rtde==1.6.5"
    rm -rf "$venv"
    "$python" -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check "ur-rtde==1.6.5"
fi

# The feature set of `cargo test --workspace` (which CI runs first): nothing compiles again.
cargo build --quiet --workspace --bins --examples
sim="$root/target/debug/sim-ur5e"

if (exec 3<>/dev/tcp/127.0.0.1/30004) 2>/dev/null; then
    echo "ur-rtde-check: port 30004 is already in use; ur_rtde can only connect there" >&2
    echo "0 passed, 1 failed"
    exit 1
fi

work="$(mktemp -d)"
sim_pid=""
cleanup() {
    if [[ -n "$sim_pid" ]]; then kill "$sim_pid" 2>/dev/null || true; wait "$sim_pid" 2>/dev/null || true; fi
    rm -rf "$work"
}
trap cleanup EXIT

RUST_LOG="${RUST_LOG:-warn}" "$sim" --rtde-port 30004 --dashboard-port 0 --primary-port 0 \
    --secondary-port 0 --realtime-port 0 --gripper-port 0 \
    --initial-q 0,-1.5707963267948966,0,-1.5707963267948966,0,0 \
    --ports-file "$work/ports.json" >"$work/sim.log" 2>&1 &
sim_pid=$!

# shellcheck source=sim-ur5e-wait.sh
source "$root/.ci/sim-ur5e-wait.sh"
wait_for_sim_ur5e ur-rtde-check

status=0
timeout 120 "$venv/bin/python" "$root/hil-tests/simulators/sim-ur5e/python/test_ur_rtde.py" "$work/ports.json" || status=$?
if [[ $status -ne 0 ]]; then
    echo "ur-rtde-check: simulator log:" >&2
    tail -n 50 "$work/sim.log" >&2
fi
exit $status
