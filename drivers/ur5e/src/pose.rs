//! The controller's pose format `p[x, y, z, rx, ry, rz]`: metres and a rotation vector
//! (axis times angle, radians) in the arm base frame.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// A TCP pose as the controller reports it (`actual_TCP_pose`) and URScript takes it (`p[...]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TcpPose {
    /// Position x (m).
    pub x_m: f64,
    /// Position y (m).
    pub y_m: f64,
    /// Position z (m).
    pub z_m: f64,
    /// Rotation vector x (rad).
    pub rx_rad: f64,
    /// Rotation vector y (rad).
    pub ry_rad: f64,
    /// Rotation vector z (rad).
    pub rz_rad: f64,
}

impl TcpPose {
    /// From the 6-vector `[x, y, z, rx, ry, rz]`.
    pub fn from_array(v: [f64; 6]) -> Self {
        Self {
            x_m: v[0],
            y_m: v[1],
            z_m: v[2],
            rx_rad: v[3],
            ry_rad: v[4],
            rz_rad: v[5],
        }
    }

    /// The 6-vector `[x, y, z, rx, ry, rz]`.
    pub fn as_array(&self) -> [f64; 6] {
        [
            self.x_m,
            self.y_m,
            self.z_m,
            self.rx_rad,
            self.ry_rad,
            self.rz_rad,
        ]
    }

    /// From an isometry (base frame -> tool).
    pub fn from_isometry(iso: &Isometry3<f64>) -> Self {
        let t = iso.translation.vector;
        let r = iso.rotation.scaled_axis();
        Self::from_array([t.x, t.y, t.z, r.x, r.y, r.z])
    }

    /// As an isometry (base frame -> tool).
    pub fn to_isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(self.x_m, self.y_m, self.z_m),
            UnitQuaternion::from_scaled_axis(Vector3::new(self.rx_rad, self.ry_rad, self.rz_rad)),
        )
    }

    /// Straight-line distance between the positions (m).
    pub fn position_distance_m(&self, other: &Self) -> f64 {
        ((self.x_m - other.x_m).powi(2)
            + (self.y_m - other.y_m).powi(2)
            + (self.z_m - other.z_m).powi(2))
        .sqrt()
    }

    /// Angle of the relative rotation (rad). Compared as rotations, not rotation vectors:
    /// at an angle of pi the vector's sign is ambiguous (reference §5.1).
    pub fn orientation_distance_rad(&self, other: &Self) -> f64 {
        self.to_isometry()
            .rotation
            .angle_to(&other.to_isometry().rotation)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opposite_rotation_vectors_at_pi_are_the_same_rotation() {
        // Angle pi about (0, 1, -1)/sqrt(2): both signs of the vector are the same rotation.
        let h = std::f64::consts::PI / 2f64.sqrt();
        let a = TcpPose::from_array([0.0, 0.0, 0.0, 0.0, h, -h]);
        let b = TcpPose::from_array([0.0, 0.0, 0.0, 0.0, -h, h]);
        assert!(a.orientation_distance_rad(&b) < 1e-9);
        let c = TcpPose::from_array([0.3, 0.4, 0.0, 0.0, 0.0, 0.5]);
        assert!((c.position_distance_m(&a) - 0.5).abs() < 1e-12);
        assert!((TcpPose::from_isometry(&c.to_isometry()).rz_rad - 0.5).abs() < 1e-12);
    }
}
