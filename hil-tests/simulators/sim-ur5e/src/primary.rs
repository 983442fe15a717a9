//! Encoders for the primary/secondary (30001/30002) state packages and the real-time (30003)
//! packet, from a [`Snapshot`] (reference §3.2-3.3).

use crate::robot::{Snapshot, robot_mode};
use ur5e::rtde::ControllerVersion;

/// Package type ROBOT_STATE.
pub const ROBOT_STATE: u8 = 16;
/// Package type ROBOT_MESSAGE.
pub const ROBOT_MESSAGE: u8 = 20;
/// Size of the RealTime 5.9 packet, size field included.
pub const REALTIME_LEN: usize = 1116;

fn sub_header(out: &mut Vec<u8>, size: u32, sub_type: u8) {
    out.extend_from_slice(&size.to_be_bytes());
    out.push(sub_type);
}

/// One ROBOT_STATE package: RobotModeData (47 bytes), JointData (251), CartesianInfo (101).
pub fn robot_state(s: &Snapshot, out: &mut Vec<u8>) {
    out.clear();
    out.extend_from_slice(&[0, 0, 0, 0, ROBOT_STATE]);
    // RobotModeData.
    sub_header(out, 47, 0);
    out.extend_from_slice(&((s.time_s * 1e6) as u64).to_be_bytes());
    let running = s.runtime_state == 2;
    let paused = s.runtime_state == 4;
    for flag in [
        true,
        s.robot_mode == robot_mode::RUNNING,
        s.robot_mode >= robot_mode::POWER_ON,
        s.safety_mode == 7,
        s.safety_mode == 3,
        running,
        paused,
    ] {
        out.push(u8::from(flag));
    }
    out.push(s.robot_mode as i8 as u8);
    out.push(0); // control mode: position
    out.extend_from_slice(&s.target_speed_fraction.to_be_bytes());
    out.extend_from_slice(&s.speed_scaling.to_be_bytes());
    out.extend_from_slice(&1.0f64.to_be_bytes());
    out.push(0);
    // JointData.
    sub_header(out, 251, 1);
    for j in 0..6 {
        out.extend_from_slice(&s.q[j].to_be_bytes());
        out.extend_from_slice(&s.target_q[j].to_be_bytes());
        out.extend_from_slice(&s.qd[j].to_be_bytes());
        out.extend_from_slice(&0.0f32.to_be_bytes()); // current
        out.extend_from_slice(&48.0f32.to_be_bytes()); // voltage
        out.extend_from_slice(&35.0f32.to_be_bytes()); // motor temperature
        out.extend_from_slice(&0.0f32.to_be_bytes()); // micro temperature (deprecated)
        out.push(s.joint_mode() as u8);
    }
    // CartesianInfo.
    sub_header(out, 101, 4);
    for v in s.tcp_pose.iter().chain(s.tcp_offset.iter()) {
        out.extend_from_slice(&v.to_be_bytes());
    }
    let len = out.len() as u32;
    out[..4].copy_from_slice(&len.to_be_bytes());
}

/// The VERSION robot message sent first on 30001/30002.
pub fn version_message(v: &ControllerVersion, out: &mut Vec<u8>) {
    out.clear();
    out.extend_from_slice(&[0, 0, 0, 0, ROBOT_MESSAGE]);
    out.extend_from_slice(&0u64.to_be_bytes());
    out.push((-2i8) as u8); // source: controller
    out.push(3); // VERSION
    let project = b"URControl";
    out.push(project.len() as u8);
    out.extend_from_slice(project);
    out.push(v.major as u8);
    out.push(v.minor as u8);
    out.extend_from_slice(&(v.bugfix as i32).to_be_bytes());
    out.extend_from_slice(&(v.build as i32).to_be_bytes());
    out.extend_from_slice(b"01-01-2025, 00:00:00");
    let len = out.len() as u32;
    out[..4].copy_from_slice(&len.to_be_bytes());
}

/// The RealTime 5.9 packet: `i32` size 1116, then 139 doubles.
pub fn realtime(s: &Snapshot, out: &mut Vec<u8>) {
    let mut d = [0.0f64; 139];
    d[0] = s.time_s;
    d[1..7].copy_from_slice(&s.target_q);
    d[7..13].copy_from_slice(&s.qd);
    d[13..19].copy_from_slice(&s.qdd);
    d[31..37].copy_from_slice(&s.q);
    d[37..43].copy_from_slice(&s.qd);
    d[55..61].copy_from_slice(&s.tcp_pose);
    d[61..67].copy_from_slice(&s.tcp_speed);
    d[73..79].copy_from_slice(&s.tcp_pose);
    d[79..85].copy_from_slice(&s.tcp_speed);
    for t in &mut d[86..92] {
        *t = 35.0;
    }
    d[92] = s.time_s;
    d[94] = f64::from(s.robot_mode);
    for m in &mut d[95..101] {
        *m = f64::from(s.joint_mode());
    }
    d[101] = f64::from(s.safety_mode);
    d[110] = -9.81;
    d[117] = s.speed_scaling;
    d[121] = 48.0;
    d[122] = 48.0;
    d[130] = s.digital_output_bits as f64;
    d[131] = f64::from(s.runtime_state);
    d[132..135].copy_from_slice(&s.elbow_position);
    d[138] = f64::from(s.safety_status_bits());
    out.clear();
    out.extend_from_slice(&(REALTIME_LEN as i32).to_be_bytes());
    for v in d {
        out.extend_from_slice(&v.to_be_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::inputs::InputTable;
    use crate::robot::{RobotInit, RobotModel};

    #[test]
    fn package_sizes_match_the_reference() {
        let mut m = RobotModel::new(RobotInit::default());
        m.step(0.002, &InputTable::new());
        let s = m.snapshot();
        let mut out = Vec::new();
        robot_state(&s, &mut out);
        assert_eq!(out.len(), 5 + 47 + 251 + 101);
        assert_eq!(
            u32::from_be_bytes([out[0], out[1], out[2], out[3]]) as usize,
            out.len()
        );
        // Sub-package sizes in place.
        assert_eq!(&out[5..10], &[0, 0, 0, 47, 0]);
        assert_eq!(&out[52..57], &[0, 0, 0, 251, 1]);
        assert_eq!(&out[303..308], &[0, 0, 0, 101, 4]);
        assert!(
            out.len() <= 2000,
            "python-urx drops packages above 2000 bytes"
        );
        realtime(&s, &mut out);
        assert_eq!(out.len(), REALTIME_LEN);
        let q0 = f64::from_be_bytes(out[4 + 31 * 8..4 + 32 * 8].try_into().unwrap());
        assert_eq!(q0, s.q[0]);
    }
}
