//! UR5e forward kinematics from the published DH table and the closed-form inverse.
//!
//! Convention: standard (distal) DH, `T_i = Rz(q_i) * Tz(d_i) * Tx(a_i) * Rx(alpha_i)`, all joint
//! offsets zero. Frame 0 is the controller's base frame (z up through the base axis), frame 6 the
//! tool flange. Numbers: UR's "Parameters for calculations of kinematics and dynamics" table,
//! copied in `shared/reference/ur5e.md` section 5.1.

use core::f64::consts::{PI, TAU};
use planar::wrap_angle;

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// Joint angles q1..q6 in radians (base, shoulder, elbow, wrist 1, wrist 2, wrist 3).
pub type Joints = [f64; 6];

/// Numerical slack for the `acos` arguments of the closed form: poses this close to the boundary
/// of the workspace (stretched arm, wrist on the base axis cylinder) still get a solution.
const ACOS_SLACK: f64 = 1e-9;

/// Below this |sin q5| the wrist is singular (axes 4 and 6 aligned) and q6 is not determined.
/// `acos` turns rounding of 1e-16 in cos q5 into ~3e-8 in q5, so the threshold sits above that;
/// the pose error of treating such a q5 as singular is below 1e-8 m.
const WRIST_SINGULAR_SIN: f64 = 1e-7;

/// Joint position limits in radians, inclusive.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointLimits {
    /// Lower limit of each joint [rad].
    pub lower_rad: Joints,
    /// Upper limit of each joint [rad].
    pub upper_rad: Joints,
}

impl Default for JointLimits {
    /// The UR5e's published +-2 pi on every joint, with the elbow held to +-pi as the ROS 2
    /// description does (beyond that the forearm hits the upper arm).
    fn default() -> Self {
        Self {
            lower_rad: [-TAU, -TAU, -PI, -TAU, -TAU, -TAU],
            upper_rad: [TAU, TAU, PI, TAU, TAU, TAU],
        }
    }
}

impl JointLimits {
    /// Whether every joint of `q` lies within its limits.
    pub fn contains(&self, q: &Joints) -> bool {
        q.iter()
            .zip(self.lower_rad.iter().zip(self.upper_rad.iter()))
            .all(|(qi, (lo, hi))| *qi >= *lo && *qi <= *hi)
    }

    /// The representative of angle `q_rad` (modulo 2 pi) that lies within the limits of joint
    /// `joint`, preferring the one nearest zero; `None` if no representative fits.
    fn fit(&self, joint: usize, q_rad: f64) -> Option<f64> {
        let wrapped = wrap_angle(q_rad);
        let (lo, hi) = (self.lower_rad[joint], self.upper_rad[joint]);
        // Nearest zero first: the wrapped value, then one turn either way.
        let alternatives = if wrapped >= 0.0 {
            [wrapped, wrapped - TAU, wrapped + TAU]
        } else {
            [wrapped, wrapped + TAU, wrapped - TAU]
        };
        alternatives.into_iter().find(|q| *q >= lo && *q <= hi)
    }
}

/// A UR5e: DH parameters and joint limits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ur5e {
    /// DH link lengths a_i [m].
    pub a_m: [f64; 6],
    /// DH link offsets d_i [m].
    pub d_m: [f64; 6],
    /// DH link twists alpha_i [rad].
    pub alpha_rad: [f64; 6],
    /// Joint position limits.
    pub limits: JointLimits,
}

impl Default for Ur5e {
    /// The published UR5e DH table (UR's kinematics FAQ) and [`JointLimits::default`].
    fn default() -> Self {
        Self {
            a_m: [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0],
            d_m: [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996],
            alpha_rad: [PI / 2.0, 0.0, 0.0, PI / 2.0, -PI / 2.0, 0.0],
            limits: JointLimits::default(),
        }
    }
}

/// The frames of the arm for one joint configuration, all in the arm base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmFrames {
    /// `frames[i]` is DH frame i (0 = base, 6 = tool flange).
    pub frames: [Isometry3<f64>; 7],
}

impl ArmFrames {
    /// Origin of DH frame `i` in the arm base frame.
    pub fn origin(&self, i: usize) -> Point3<f64> {
        Point3::from(self.frames[i].translation.vector)
    }

    /// z axis (joint axis i+1 for i < 6) of DH frame `i` in the arm base frame.
    pub fn z_axis(&self, i: usize) -> Vector3<f64> {
        self.frames[i].rotation * Vector3::z()
    }

    /// The tool flange pose (frame 6).
    pub fn flange(&self) -> Isometry3<f64> {
        self.frames[6]
    }
}

/// The rotation and translation of one DH link as plain matrices (cheaper than composing
/// isometries built from axis-angle rotations).
#[inline]
fn dh_link(a: f64, d: f64, alpha: f64, theta: f64) -> (Matrix3<f64>, Vector3<f64>) {
    let (st, ct) = theta.sin_cos();
    let (sa, ca) = alpha.sin_cos();
    let r = Matrix3::new(ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0.0, sa, ca);
    let t = Vector3::new(a * ct, a * st, d);
    (r, t)
}

fn isometry(r: Matrix3<f64>, t: Vector3<f64>) -> Isometry3<f64> {
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Isometry3::from_parts(Translation3::from(t), rotation)
}

impl Ur5e {
    /// Forward kinematics: the tool flange pose in the arm base frame for joints `q`.
    pub fn forward(&self, q: &Joints) -> Isometry3<f64> {
        let (r, t) = self.forward_matrix(q);
        isometry(r, t)
    }

    /// Forward kinematics as a rotation matrix and a translation (flange in the arm base frame).
    pub fn forward_matrix(&self, q: &Joints) -> (Matrix3<f64>, Vector3<f64>) {
        let mut r = Matrix3::identity();
        let mut t = Vector3::zeros();
        for (i, qi) in q.iter().enumerate() {
            let (ri, ti) = dh_link(self.a_m[i], self.d_m[i], self.alpha_rad[i], *qi);
            t += r * ti;
            r *= ri;
        }
        (r, t)
    }

    /// Every DH frame (base, joints 1..5, flange) in the arm base frame for joints `q`.
    pub fn frames(&self, q: &Joints) -> ArmFrames {
        let mut frames = [Isometry3::identity(); 7];
        let mut r = Matrix3::identity();
        let mut t = Vector3::zeros();
        for (i, qi) in q.iter().enumerate() {
            let (ri, ti) = dh_link(self.a_m[i], self.d_m[i], self.alpha_rad[i], *qi);
            t += r * ti;
            r *= ri;
            frames[i + 1] = isometry(r, t);
        }
        ArmFrames { frames }
    }

    /// Origins of DH frames 0..6 and the unit z axes of frames 0..6, in the arm base frame.
    /// The allocation-free core of the collision check.
    pub fn origins_and_axes(&self, q: &Joints) -> ([Vector3<f64>; 7], [Vector3<f64>; 7]) {
        let mut origins = [Vector3::zeros(); 7];
        let mut axes = [Vector3::z(); 7];
        let mut r = Matrix3::identity();
        let mut t = Vector3::zeros();
        for (i, qi) in q.iter().enumerate() {
            let (ri, ti) = dh_link(self.a_m[i], self.d_m[i], self.alpha_rad[i], *qi);
            t += r * ti;
            r *= ri;
            origins[i + 1] = t;
            axes[i + 1] = r.column(2).into_owned();
        }
        (origins, axes)
    }

    /// Closed-form inverse kinematics: every solution (up to 8) that puts the tool flange at
    /// `flange` (in the arm base frame) and lies within the joint limits. Each angle is the
    /// representative (mod 2 pi) within the limits nearest zero. At a wrist singularity
    /// (sin q5 = 0) q6 is free and set to 0.
    pub fn inverse(&self, flange: &Isometry3<f64>) -> heapless::Vec<Joints, 8> {
        let r = flange.rotation.to_rotation_matrix().into_inner();
        let p = flange.translation.vector;
        let mut out = heapless::Vec::new();
        self.inverse_matrix(&r, &p, 0.0, |q| {
            if let Some(fitted) = self.fit_limits(&q) {
                // Capacity 8 = number of closed-form branches, so this cannot overflow.
                let _ = out.push(fitted);
            }
            true
        });
        out
    }

    /// All closed-form solutions for flange rotation `r` and position `p` (arm base frame),
    /// before joint limits, with angles wrapped into (-pi, pi]. `q6_singular_rad` is used for q6
    /// at a wrist singularity. `visit` is called once per solution in branch order
    /// (shoulder, wrist, elbow) and may return `false` to stop early. Returns the number of
    /// solutions visited.
    pub fn inverse_matrix(
        &self,
        r: &Matrix3<f64>,
        p: &Vector3<f64>,
        q6_singular_rad: f64,
        mut visit: impl FnMut(Joints) -> bool,
    ) -> usize {
        let [d1, _, _, d4, d5, d6] = self.d_m;
        let (a2, a3) = (self.a_m[1], self.a_m[2]);
        let z6 = r.column(2).into_owned();
        // Wrist centre: origin of frame 5 = flange - d6 * z6.
        let p5 = p - d6 * z6;
        let rho = (p5.x * p5.x + p5.y * p5.y).sqrt();
        if rho < d4.abs() - ACOS_SLACK || rho == 0.0 {
            return 0; // wrist inside the shoulder-offset cylinder: no q1
        }
        // q1: the wrist centre lies d4 off the plane of joints 2..4: sin(q1 - phi) = d4 / rho.
        let phi = p5.y.atan2(p5.x);
        let beta = (d4 / rho).clamp(-1.0, 1.0).asin();
        let mut visited = 0;
        for q1 in [phi + beta, phi + PI - beta] {
            let (s1, c1) = q1.sin_cos();
            // q5: flange height over that plane is d4 + d6 cos q5.
            let c5 = (p.x * s1 - p.y * c1 - d4) / d6;
            if c5.abs() > 1.0 + ACOS_SLACK {
                continue;
            }
            let q5_abs = c5.clamp(-1.0, 1.0).acos();
            for q5 in [q5_abs, -q5_abs] {
                let s5 = q5.sin();
                // q6: joint axis 1 seen from the flange is (s5 c6, -s5 s6, c5).
                let wx = r[(0, 0)] * s1 - r[(1, 0)] * c1;
                let wy = r[(0, 1)] * s1 - r[(1, 1)] * c1;
                let q6 = if s5.abs() < WRIST_SINGULAR_SIN {
                    q6_singular_rad
                } else {
                    (-wy / s5).atan2(wx / s5)
                };
                // Frame 4 in frame 1: T14 = T01^-1 * T06 * T56^-1 * T45^-1.
                let (r01, t01) = dh_link(0.0, d1, self.alpha_rad[0], q1);
                let (r45, t45) = dh_link(0.0, d5, self.alpha_rad[4], q5);
                let (r56, t56) = dh_link(0.0, d6, self.alpha_rad[5], q6);
                // T04 = T06 * T56^-1 * T45^-1
                let r05 = r * r56.transpose();
                let t05 = p - r05 * t56;
                let r04 = r05 * r45.transpose();
                let t04 = t05 - r04 * t45;
                let r14 = r01.transpose() * r04;
                let t14 = r01.transpose() * (t04 - t01);
                // Planar 2R in frame 1: origin 4 = (a2 c2 + a3 c23, a2 s2 + a3 s23, d4).
                let (x, y) = (t14.x, t14.y);
                let c3 = (x * x + y * y - a2 * a2 - a3 * a3) / (2.0 * a2 * a3);
                if c3.abs() > 1.0 + ACOS_SLACK {
                    continue;
                }
                let q3_abs = c3.clamp(-1.0, 1.0).acos();
                // q2 + q3 + q4 is the angle of x4 in frame 1.
                let q234 = r14[(1, 0)].atan2(r14[(0, 0)]);
                for q3 in [q3_abs, -q3_abs] {
                    let s3 = q3.sin();
                    let q2 = y.atan2(x) - (a3 * s3).atan2(a2 + a3 * c3);
                    let q4 = q234 - q2 - q3;
                    visited += 1;
                    let q = [q1, q2, q3, q4, q5, q6].map(wrap_angle);
                    if !visit(q) {
                        return visited;
                    }
                }
            }
        }
        visited
    }

    /// `q` moved into the joint limits joint by joint (mod 2 pi), or `None` if some joint fits
    /// no representative.
    pub fn fit_limits(&self, q: &Joints) -> Option<Joints> {
        let mut out = [0.0; 6];
        for (j, qj) in q.iter().enumerate() {
            out[j] = self.limits.fit(j, *qj)?;
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::FRAC_PI_2;

    fn assert_pose(iso: &Isometry3<f64>, p: [f64; 3], rotvec: [f64; 3]) {
        let expected_r = Rotation3::new(Vector3::from(rotvec));
        let dp = (iso.translation.vector - Vector3::from(p)).norm();
        assert!(
            dp < 1e-4,
            "position {:?} vs {:?}",
            iso.translation.vector,
            p
        );
        let angle = iso
            .rotation
            .to_rotation_matrix()
            .rotation_to(&expected_r)
            .angle();
        assert!(angle < 1e-4, "rotation off by {angle} rad");
    }

    #[test]
    fn forward_matches_reference_test_vectors() {
        let arm = Ur5e::default();
        assert_pose(
            &arm.forward(&[0.0; 6]),
            [-0.8172, -0.2329, 0.0628],
            [FRAC_PI_2, 0.0, 0.0],
        );
        assert_pose(
            &arm.forward(&[0.0, -FRAC_PI_2, 0.0, -FRAC_PI_2, 0.0, 0.0]),
            [0.0, -0.2329, 1.0794],
            [0.0, 2.2214, -2.2214],
        );
        assert_pose(
            &arm.forward(&[0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0]),
            [-0.4919, -0.1333, 0.4879],
            [2.2214, 2.2214, 0.0],
        );
    }

    #[test]
    fn frames_end_at_the_flange() {
        let arm = Ur5e::default();
        let q = [0.3, -1.1, 0.7, -0.4, 1.2, -2.0];
        let frames = arm.frames(&q);
        let fk = arm.forward(&q);
        assert!((frames.flange().translation.vector - fk.translation.vector).norm() < 1e-12);
        assert!(frames.flange().rotation.angle_to(&fk.rotation) < 1e-9);
        // Joint 2 sits d1 above the base on the base axis whatever q1 is.
        assert!((frames.origin(1) - Point3::new(0.0, 0.0, 0.1625)).norm() < 1e-12);
    }
}
