"""Third-party client check: ur_rtde 1.6.5 (PyPI `ur-rtde`) against the simulated UR5e.

Run by .ci/ur-rtde-check.sh, which starts `sim-ur5e` with RTDE on 30004 (ur_rtde's
RTDEReceiveInterface takes no port) and the other ports chosen by the OS, written to a JSON
file given as the first argument. The simulator starts at q = (0, -pi/2, 0, -pi/2, 0, 0),
whose flange position is (0, -0.2329, 1.0794) m (reference table, docs/ur5e.md).

Prints one line per check and closes with `N passed, N failed`; exits non-zero on a failure.
"""

import json
import math
import socket
import sys
import time

import dashboard_client
import rtde_io
import rtde_receive

HOST = "127.0.0.1"
INITIAL_Q = [0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0, 0.0]
INITIAL_FLANGE_XYZ = [0.0, -0.2329, 1.0794]

results = []


def check(name):
    def wrap(fn):
        try:
            fn()
            results.append((name, None))
            print(f"PASS {name}", flush=True)
        except Exception as e:  # noqa: BLE001 - every failure is reported, none aborts the run
            results.append((name, e))
            print(f"FAIL {name}: {type(e).__name__}: {e}", flush=True)
        return fn

    return wrap


def close(a, b, tol):
    return len(a) == len(b) and all(abs(x - y) <= tol for x, y in zip(a, b))


def wait_until(pred, timeout_s, what):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return
        time.sleep(0.01)
    raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")


ports = json.load(open(sys.argv[1]))
state = {}


@check("RTDEReceiveInterface connects at the controller's 500 Hz")
def _():
    r = rtde_receive.RTDEReceiveInterface(HOST)
    assert r.isConnected(), "not connected"
    state["r"] = r


@check("getActualQ is the initial pose")
def _():
    q = state["r"].getActualQ()
    assert close(q, INITIAL_Q, 1e-9), q


@check("getActualTCPPose follows the UR5e kinematics")
def _():
    pose = state["r"].getActualTCPPose()
    assert close(pose[:3], INITIAL_FLANGE_XYZ, 1e-3), pose


@check("timestamps advance at the control rate")
def _():
    r = state["r"]
    t0 = r.getTimestamp()
    time.sleep(0.5)
    t1 = r.getTimestamp()
    assert 0.25 <= t1 - t0 <= 0.9, (t0, t1)
    # 500 Hz: consecutive distinct timestamps are 2 ms apart.
    seen = set()
    deadline = time.monotonic() + 0.2
    while time.monotonic() < deadline:
        seen.add(round(r.getTimestamp(), 6))
        time.sleep(0.0005)
    stamps = sorted(seen)
    steps = [round(b - a, 6) for a, b in zip(stamps, stamps[1:])]
    assert steps and min(steps) >= 0.0019, steps[:10]


@check("robot, safety and runtime state of an idle running robot")
def _():
    r = state["r"]
    assert r.getRobotMode() == 7, r.getRobotMode()
    assert r.getSafetyMode() == 1, r.getSafetyMode()
    assert r.getRuntimeState() == 1, r.getRuntimeState()
    assert not r.isProtectiveStopped()
    assert not r.isEmergencyStopped()
    assert list(r.getJointMode()) == [253] * 6, r.getJointMode()
    assert r.getSafetyStatusBits() == 1, r.getSafetyStatusBits()
    assert r.getSpeedScaling() == 1.0


@check("two receive interfaces stream at once")
def _():
    r2 = rtde_receive.RTDEReceiveInterface(HOST)
    t0 = (state["r"].getTimestamp(), r2.getTimestamp())
    time.sleep(0.2)
    t1 = (state["r"].getTimestamp(), r2.getTimestamp())
    assert t1[0] > t0[0] and t1[1] > t0[1], (t0, t1)
    r2.disconnect()


@check("DashboardClient connects and answers")
def _():
    d = dashboard_client.DashboardClient(HOST, ports["dashboard"])
    d.connect()
    assert d.isConnected()
    assert d.robotmode() == "Robotmode: RUNNING", d.robotmode()
    assert d.isInRemoteControl() is True
    version = d.polyscopeVersion()
    assert "5.21.0" in version, version
    assert d.getSerialNumber().isdigit(), d.getSerialNumber()
    assert d.safetystatus() == "Safetystatus: NORMAL", d.safetystatus()
    assert d.running() is False
    assert d.programState().startswith("STOPPED"), d.programState()
    assert d.getRobotModel().startswith("UR"), d.getRobotModel()
    d.stop()  # ur_rtde throws unless the reply is exactly "Stopped"
    state["d"] = d


@check("a movej sent on 30002 is seen through ur_rtde, within the joint speed limit")
def _():
    r = state["r"]
    goal = [2.0, -1.2, 0.4, -1.4, 0.3, 0.2]
    with socket.create_connection((HOST, ports["secondary"]), timeout=2) as s:
        s.sendall(
            ("def check_move():\n  movej([%s], a=10.0, v=3.0)\nend\n" % ", ".join(map(str, goal))).encode()
        )
        wait_until(lambda: r.getRuntimeState() == 2, 2.0, "program running")
        top = 0.0
        deadline = time.monotonic() + 5.0
        while r.getRuntimeState() == 2 and time.monotonic() < deadline:
            top = max(top, max(abs(v) for v in r.getActualQd()))
            time.sleep(0.002)
    assert close(r.getActualQ(), goal, 1e-6), r.getActualQ()
    assert top <= math.pi + 1e-6, top
    assert top > 2.0, f"peak joint speed {top} rad/s: the move should run near the limit"


@check("dashboard power off / on / brake release is seen on RTDE")
def _():
    r, d = state["r"], state["d"]
    d.powerOff()
    wait_until(lambda: r.getRobotMode() == 3, 2.0, "POWER_OFF on RTDE")
    d.powerOn()
    wait_until(lambda: r.getRobotMode() == 5, 3.0, "IDLE on RTDE")
    d.brakeRelease()
    wait_until(lambda: r.getRobotMode() == 7, 3.0, "RUNNING on RTDE")
    assert d.robotmode() == "Robotmode: RUNNING"


@check("RTDEIOInterface inputs (no start, many recipes) reach the controller")
def _():
    r = state["r"]
    io = rtde_io.RTDEIOInterface(HOST)
    assert io.setStandardDigitalOut(0, True)
    wait_until(lambda: r.getActualDigitalOutputBits() & 1 == 1, 2.0, "digital output 0 on")
    assert io.setStandardDigitalOut(0, False)
    wait_until(lambda: r.getActualDigitalOutputBits() & 1 == 0, 2.0, "digital output 0 off")
    assert io.setSpeedSlider(0.5)
    wait_until(lambda: abs(r.getTargetSpeedFraction() - 0.5) < 1e-9, 2.0, "speed slider 0.5")
    assert io.setSpeedSlider(1.0)
    io.disconnect()  # sends P on a never-started connection and waits for the reply


@check("clients disconnect cleanly")
def _():
    state["d"].disconnect()
    state["r"].disconnect()
    assert not state["r"].isConnected()


passed = sum(1 for _, e in results if e is None)
failed = len(results) - passed
print(f"{passed} passed, {failed} failed")
sys.exit(1 if failed else 0)
