#!/usr/bin/env python3
"""Writes drivers/rmp-base/rmp.dbc (factory-default feedback) and rmp-driver.dbc (the driver's
default feedback selection) from the item table in firmware-like/rmp-codec/src/feedback.rs.

Run from the workspace root after changing the item table or the driver's selection; the test
drivers/rmp-base/tests/dbc.rs then checks both files against the codec.
"""
import re

SRC = open("firmware-like/rmp-codec/src/feedback.rs").read()
ITEMS = re.findall(r'^\s+(\w+) = (\d+), "([^"]+)", (\w+), "([^"]*)";', SRC, re.M)
assert len(ITEMS) == 96, len(ITEMS)

# Keep in step with rmp_base::DRIVER_FEEDBACK_ITEMS (the test compares them).
DRIVER_ITEMS = [0, 1, 2, 3, 9, 11, 24, 25, 27, 28, 33, 34, 35, 36, 37, 85]


def sig(name, start, length, signed, lo, hi, unit, rx):
    sign = "-" if signed else "+"
    return f' SG_ {name} : {start}|{length}@0{sign} (1,0) [{lo}|{hi}] "{unit}" {rx}'


def write(path, item_indices, comment, with_gen1):
    out = []
    w = out.append
    floats = []
    w('VERSION "grop-rmp-1"')
    w("")
    w("NS_ :")
    for ns in ["NS_DESC_", "CM_", "BA_DEF_", "BA_", "VAL_", "BA_DEF_DEF_", "SIG_VALTYPE_"]:
        w("\t" + ns)
    w("")
    w("BS_:")
    w("")
    w("BU_: HOST RMP")
    w("")
    w("BO_ 1280 RMP_V3_MOTION: 8 HOST")
    w(sig("velocity_norm", 7, 32, True, -1, 1, "", "RMP"))
    w(sig("yaw_rate_norm", 39, 32, True, -1, 1, "", "RMP"))
    floats += [(1280, "velocity_norm"), (1280, "yaw_rate_norm")]
    w("")
    w("BO_ 1281 RMP_V3_CONFIG: 8 HOST")
    w(sig("config_command_id", 7, 32, False, 0, 35, "", "RMP"))
    w(sig("config_parameter", 39, 32, False, 0, 4294967295, "", "RMP"))
    w("")
    state_frame = None
    for k in range((len(item_indices) + 1) // 2):
        fid = 0x502 + k
        w(f"BO_ {fid} RMP_V3_FEEDBACK_{k:02d}: 8 RMP")
        for j, start in ((0, 7), (1, 39)):
            if 2 * k + j >= len(item_indices):
                continue
            _, idx, name, kind, unit = ITEMS[item_indices[2 * k + j]]
            if name == "operational_state":
                state_frame = fid
            if kind == "F32":
                w(sig(name, start, 32, True, 0, 0, unit, "HOST"))
                floats.append((fid, name))
            else:
                w(sig(name, start, 32, False, 0, 4294967295, unit, "HOST"))
        w("")
    if with_gen1:
        def g1(fid, mname, tx, rx, slots):
            w(f"BO_ {fid} {mname}: 8 {tx}")
            for k, s in enumerate(slots):
                if s is None:
                    continue
                name, signed = s
                lo, hi = (-32768, 32767) if signed else (0, 65535)
                w(sig(name, k * 16 + 7, 16, signed, lo, hi, "", rx))
            w("")
        g1(0x413, "RMP_GEN1_MOTION", "HOST", "RMP", [("gen1_velocity_counts", True), ("gen1_turn_counts", True), ("gen1_config_command_id", False), ("gen1_config_parameter", False)])
        g1(0x412, "RMP_GEN1_SHUTDOWN", "HOST", "RMP", [])
        g1(0x400, "RMP_GEN1_BUILD", "RMP", "HOST", [("gen1_build_id", False)])
        g1(0x401, "RMP_GEN1_ATTITUDE", "RMP", "HOST", [("gen1_pitch_counts", True), ("gen1_pitch_rate_counts", True), ("gen1_roll_counts", True), ("gen1_roll_rate_counts", True)])
        g1(0x402, "RMP_GEN1_VELOCITY", "RMP", "HOST", [("gen1_left_wheel_vel_counts", True), ("gen1_right_wheel_vel_counts", True), ("gen1_yaw_rate_counts", True), ("gen1_servo_frame_counter", False)])
        g1(0x403, "RMP_GEN1_WHEEL_DISPLACEMENT", "RMP", "HOST", [("gen1_left_wheel_disp_lo", False), ("gen1_left_wheel_disp_hi", False), ("gen1_right_wheel_disp_lo", False), ("gen1_right_wheel_disp_hi", False)])
        g1(0x404, "RMP_GEN1_INTEGRATED", "RMP", "HOST", [("gen1_fore_aft_disp_lo", False), ("gen1_fore_aft_disp_hi", False), ("gen1_yaw_disp_lo", False), ("gen1_yaw_disp_hi", False)])
        g1(0x405, "RMP_GEN1_TORQUE", "RMP", "HOST", [("gen1_left_motor_torque_counts", True), ("gen1_right_motor_torque_counts", True)])
        g1(0x406, "RMP_GEN1_MODE_BATTERY", "RMP", "HOST", [("gen1_operational_mode", False), ("gen1_gain_schedule", False), ("gen1_ui_battery_counts", False), ("gen1_base_battery_counts", False)])
        g1(0x407, "RMP_GEN1_COMMAND_ECHO", "RMP", "HOST", [("gen1_velocity_echo_counts", True), ("gen1_turn_echo_counts", True)])
        g1(0x680, "RMP_GEN1_STATUS", "RMP", "HOST", [None, ("gen1_status_word_1", False), ("gen1_status_word_2", False)])
    w(f'CM_ "{comment}";')
    w('CM_ BO_ 1280 "Normalised motion command: 1.0 = the NVM velocity / yaw-rate limit.";')
    w('CM_ BO_ 1281 "Configuration / general-purpose command (Segway Inc 2014 numbering); the parameter is a u32 or a float32 bit pattern depending on the command.";')
    w("")
    w('VAL_ 1281 config_command_id 0 "NONE" 1 "SET_MAX_VELOCITY" 2 "SET_MAX_ACCELERATION" 3 "SET_MAX_DECELERATION" 4 "SET_MAX_DTZ_DECEL" 5 "SET_COASTDOWN_ACCEL" 6 "SET_MAX_TURN_RATE" 7 "SET_MAX_TURN_ACCEL" 8 "SET_TIRE_DIAMETER" 9 "SET_WHEEL_BASE" 10 "SET_TRACK_WIDTH" 11 "SET_TRANSMISSION_RATIO" 12 "SET_INPUT_CONFIG_BITMAP" 13 "SET_ETH_IP" 14 "SET_ETH_PORT" 15 "SET_ETH_SUBNET" 16 "SET_ETH_GATEWAY" 17 "SET_USER_FEEDBACK_BITMAP_1" 18 "SET_USER_FEEDBACK_BITMAP_2" 19 "SET_USER_FEEDBACK_BITMAP_3" 20 "SET_USER_FEEDBACK_BITMAP_4" 30 "FORCE_CONFIG_FEEDBACK" 31 "AUDIO" 32 "SET_OPERATIONAL_MODE" 33 "SEND_FAULT_LOG" 34 "RESET_INTEGRATORS" 35 "RESET_PARAMS_TO_DEFAULT" ;')
    if state_frame:
        w(f'VAL_ {state_frame} operational_state 0 "CCU_INIT" 1 "PROPULSION_INIT" 2 "CHECK_STARTUP" 3 "STANDBY" 4 "TRACTOR" 5 "DISABLE_POWER" ;')
    if with_gen1:
        w('VAL_ 1030 gen1_operational_mode 0 "DISABLED" 1 "TRACTOR" 2 "BALANCE" 3 "POWER_DOWN" ;')
    w("")
    for fid, name in floats:
        w(f"SIG_VALTYPE_ {fid} {name} : 1;")
    open(path, "w").write("\n".join(out) + "\n")


write(
    "drivers/rmp-base/rmp.dbc",
    list(range(96)),
    "Segway RMP host protocols as implemented by grop rmp-codec. Family B1 (RMP v3, Segway Inc 2014 firmware numbering) on 0x500/0x501 and the feedback frames 0x502..0x531 in the DEFAULT FEEDBACK CONFIGURATION (factory): user feedback bitmaps 1..3 = 0xFFFFFFFF, bitmap 4 = 0 (96 items, 48 frames, two big-endian 32-bit words per frame). Another bitmap selection moves items to other frames; for the rmp-base driver's own selection use rmp-driver.dbc. Family A (Gen-1, RMP 50..400) on 0x0400..0x0407, 0x0412, 0x0413, 0x0680: 16-bit big-endian slots; 32-bit displacements are split low word first, so they appear as _lo/_hi pairs. See docs/rmp.md.",
    True,
)
write(
    "drivers/rmp-base/rmp-driver.dbc",
    DRIVER_ITEMS,
    "Segway RMP v3 (Segway Inc 2014 firmware) as the grop rmp-base driver configures it: DRIVER FEEDBACK CONFIGURATION, user feedback bitmaps = 0x%08X 0x%08X 0x%08X 0x00000000 (16 items, 8 frames 0x502..0x509). See docs/rmp.md."
    % tuple(sum(1 << (i - 32 * b) for i in DRIVER_ITEMS if 32 * b <= i < 32 * b + 32) for b in range(3)),
    False,
)
