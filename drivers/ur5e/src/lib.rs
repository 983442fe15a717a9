//! UR5e drivers: RTDE, dashboard, URScript, gripper, arm skills.
