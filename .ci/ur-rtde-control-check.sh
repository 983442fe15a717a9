#!/usr/bin/env bash
# Third-party client check: ur_rtde 1.6.5's RTDEControlInterface (PyPI `ur-rtde`) and
# python-urx (PyPI `urx`) against the simulated UR5e (`sim-ur5e`).
#
# Neither client takes a port: ur_rtde uses the controller's 29999, 30003 and 30004, python-urx
# 30002. The simulator therefore listens on those fixed ports, and this check runs alone, never
# beside another simulator on them. The venv lives in target/ur-rtde-venv (shared with
# .ci/ur-rtde-check.sh) and is reused. Closing line of the Python test: `N passed, N failed`;
# the script exits non-zero on any failure.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
target="${CARGO_TARGET_DIR:-$root/target}"
venv="$root/target/ur-rtde-venv"
python="${PYTHON:-python3}"

if ! "$venv/bin/python" -c "import rtde_control, rtde_receive, urx" 2>/dev/null; then
    echo "ur-rtde-control-check: installing ur-rtde==1.6.5 and urx==0.11.0 into $venv"
    [[ -x "$venv/bin/python" ]] || "$python" -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check "ur-rtde==1.6.5" "urx==0.11.0"
fi

# The feature set of `cargo test --workspace` (which CI runs first): nothing compiles again.
cargo build --quiet --workspace --bins --examples
sim="$target/debug/sim-ur5e"

for port in 29999 30002 30003 30004; do
    if (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null; then
        echo "ur-rtde-control-check: port $port is already in use; the clients can only connect there" >&2
        echo "0 passed, 1 failed"
        exit 1
    fi
done

work="$(mktemp -d)"
sim_pid=""
cleanup() {
    if [[ -n "$sim_pid" ]]; then kill "$sim_pid" 2>/dev/null || true; wait "$sim_pid" 2>/dev/null || true; fi
    rm -rf "$work"
}
trap cleanup EXIT

RUST_LOG="${RUST_LOG:-warn}" "$sim" --rtde-port 30004 --dashboard-port 29999 --primary-port 0 \
    --secondary-port 30002 --realtime-port 30003 --gripper-port 0 \
    --ports-file "$work/ports.json" >"$work/sim.log" 2>&1 &
sim_pid=$!

# shellcheck source=sim-ur5e-wait.sh
source "$root/.ci/sim-ur5e-wait.sh"
wait_for_sim_ur5e ur-rtde-control-check

status=0
timeout 100 "$venv/bin/python" "$root/hil-tests/simulators/sim-ur5e/python/test_ur_rtde_control.py" || status=$?
if [[ $status -ne 0 ]]; then
    echo "ur-rtde-control-check: simulator log:" >&2
    tail -n 50 "$work/sim.log" >&2
fi
exit $status
