# Sourced by the third-party UR client checks: waits until the simulated UR5e started by the
# caller ($sim_pid, logging to $work/sim.log) has written its ports file ($work/ports.json).
# On failure prints why and the closing line `0 passed, 1 failed`, and exits the caller.
wait_for_sim_ur5e() {
    local name="$1"
    for _ in $(seq 1 100); do
        [[ -s "$work/ports.json" ]] && return 0
        if ! kill -0 "$sim_pid" 2>/dev/null; then
            echo "$name: sim-ur5e exited early:" >&2
            cat "$work/sim.log" >&2
            echo "0 passed, 1 failed"
            exit 1
        fi
        sleep 0.1
    done
    echo "$name: sim-ur5e did not start listening" >&2
    echo "0 passed, 1 failed"
    exit 1
}
