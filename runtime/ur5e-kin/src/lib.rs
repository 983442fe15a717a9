//! UR5e kinematics: DH forward kinematics, closed-form inverse kinematics, collision primitives.
