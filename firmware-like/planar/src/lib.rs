//! The one planar pose and angle wrap of the workspace, `#![no_std]` and without heap.
//!
//! - [`wrap_angle`] / [`wrap_angle_f32`]: an angle into the half-open interval **(-pi, pi]**
//!   (pi itself stays pi; -pi becomes pi). The arithmetic is the one ur5e-kin's inverse
//!   kinematics, world's lattice and the simulated lidar had (ur5e-kin's joint-path tests get
//!   their scenario's IK branch from a tie that close): the Euclidean remainder modulo the float `TAU` (`%` is exact, then one
//!   addition of `TAU` for a negative remainder, which rounds), less `TAU` above pi (exact, by
//!   Sterbenz's lemma). So an angle in [0, pi] keeps its bits, a negative one comes back rounded
//!   to the spacing of floats near `TAU` (8.9e-16 rad in f64), and wrapping twice is wrapping
//!   once, to the bit. NaN and infinities give NaN.
//! - [`Pose2`] (f64: the world, the planners, the executive, the simulators) and [`Pose2F32`]
//!   (f32: the firmware-like control laws): x, y (m) and yaw (rad, counter-clockwise from +x),
//!   with composition, inverse, point transforms, distance and arc motion. The two have the
//!   same methods; [`Pose2::to_f32`] and `Pose2::from(Pose2F32)` convert.
//!
//! Feature `std`: the f64 sines, cosines and hypot come from std (the platform's maths
//! library, as every hosted crate of the workspace had them) instead of the `libm` crate; the
//! f32 maths is the `libm` crate's either way (as motion-control had it). Feature `serde`:
//! `Serialize`/`Deserialize` with the field names `x_m`, `y_m`, `yaw_rad` and unknown fields
//! refused (the scene and robot files' format).
//!
//! ```
//! use planar::{Pose2, wrap_angle};
//! use core::f64::consts::{FRAC_PI_2, PI};
//!
//! assert_eq!(wrap_angle(PI), PI);
//! assert_eq!(wrap_angle(-PI), PI);
//! let base = Pose2::new(1.0, 2.0, FRAC_PI_2);
//! let (x, y) = base.transform_point(1.0, 0.0);
//! assert!((x - 1.0).abs() < 1e-12 && (y - 3.0).abs() < 1e-12);
//! let back = base.compose(&base.inverse());
//! assert!(back.distance_m(&Pose2::default()) < 1e-12 && back.yaw_rad.abs() < 1e-12);
//! ```

#![no_std]

#[cfg(any(feature = "std", test))]
extern crate std;

/// The maths the types need, per precision.
mod math {
    #[cfg(feature = "std")]
    pub(crate) fn sin_cos(a: f64) -> (f64, f64) {
        a.sin_cos()
    }
    #[cfg(not(feature = "std"))]
    pub(crate) fn sin_cos(a: f64) -> (f64, f64) {
        libm::sincos(a)
    }
    #[cfg(feature = "std")]
    pub(crate) fn sin(a: f64) -> f64 {
        a.sin()
    }
    #[cfg(not(feature = "std"))]
    pub(crate) fn sin(a: f64) -> f64 {
        libm::sin(a)
    }
    #[cfg(feature = "std")]
    pub(crate) fn cos(a: f64) -> f64 {
        a.cos()
    }
    #[cfg(not(feature = "std"))]
    pub(crate) fn cos(a: f64) -> f64 {
        libm::cos(a)
    }
    #[cfg(feature = "std")]
    pub(crate) fn hypot(x: f64, y: f64) -> f64 {
        x.hypot(y)
    }
    #[cfg(not(feature = "std"))]
    pub(crate) fn hypot(x: f64, y: f64) -> f64 {
        libm::hypot(x, y)
    }
    pub(crate) fn sin_cos_f32(a: f32) -> (f32, f32) {
        (libm::sinf(a), libm::cosf(a))
    }
    pub(crate) fn sin_f32(a: f32) -> f32 {
        libm::sinf(a)
    }
    pub(crate) fn cos_f32(a: f32) -> f32 {
        libm::cosf(a)
    }
    pub(crate) fn hypot_f32(x: f32, y: f32) -> f32 {
        libm::hypotf(x, y)
    }
}

macro_rules! wrap_fn {
    ($(#[$doc:meta])* $name:ident, $t:ident) => {
        $(#[$doc])*
        #[inline]
        pub fn $name(rad: $t) -> $t {
            use core::$t::consts::{PI, TAU};
            // The Euclidean remainder in [0, TAU] (TAU only where a tiny negative remainder
            // rounds up to it), as std's `rem_euclid`, which core lacks: `%` is exact.
            let rem = rad % TAU;
            let rem = if rem < 0.0 { rem + TAU } else { rem };
            // Above pi: one turn less; rem in (PI, TAU], so the difference is exact.
            if rem > PI { rem - TAU } else { rem }
        }
    };
}

wrap_fn!(
    /// Wraps an angle (rad) into (-pi, pi] (see the crate docs for the rounding: an angle in
    /// [0, pi] is returned unchanged, a negative one to 8.9e-16 rad); NaN and infinities give
    /// NaN.
    wrap_angle,
    f64
);
wrap_fn!(
    /// [`wrap_angle`] in f32: into (-pi, pi] of f32's pi, the same arithmetic (an angle in
    /// [0, pi] unchanged, a negative one rounded to 4.8e-7 rad); NaN and infinities give NaN.
    wrap_angle_f32,
    f32
);

macro_rules! pose_type {
    (
        $(#[$doc:meta])* $name:ident, $t:ident, $wrap:ident,
        $sin_cos:path, $sin:path, $cos:path, $hypot:path
    ) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq, Default)]
        #[cfg_attr(
            feature = "serde",
            derive(serde::Serialize, serde::Deserialize),
            serde(deny_unknown_fields)
        )]
        pub struct $name {
            /// x (m).
            pub x_m: $t,
            /// y (m).
            pub y_m: $t,
            /// Heading about +z (rad), counter-clockwise from +x.
            pub yaw_rad: $t,
        }

        impl $name {
            /// The identity: the origin, facing +x.
            pub const IDENTITY: Self = Self::new(0.0, 0.0, 0.0);

            /// A pose.
            pub const fn new(x_m: $t, y_m: $t, yaw_rad: $t) -> Self {
                Self { x_m, y_m, yaw_rad }
            }

            /// `self` followed by `local` (a pose expressed in `self`'s frame): `local` in the
            /// frame `self` is expressed in. The heading is wrapped into (-pi, pi].
            pub fn compose(&self, local: &Self) -> Self {
                let (s, c) = $sin_cos(self.yaw_rad);
                Self {
                    x_m: self.x_m + c * local.x_m - s * local.y_m,
                    y_m: self.y_m + s * local.x_m + c * local.y_m,
                    yaw_rad: $wrap(self.yaw_rad + local.yaw_rad),
                }
            }

            /// The inverse transform: `p.compose(&p.inverse())` is the identity (to rounding).
            pub fn inverse(&self) -> Self {
                let (s, c) = $sin_cos(self.yaw_rad);
                Self {
                    x_m: -(c * self.x_m + s * self.y_m),
                    y_m: -(-s * self.x_m + c * self.y_m),
                    yaw_rad: $wrap(-self.yaw_rad),
                }
            }

            /// A point given in this pose's frame, in the frame the pose is expressed in.
            pub fn transform_point(&self, x_m: $t, y_m: $t) -> ($t, $t) {
                let (s, c) = $sin_cos(self.yaw_rad);
                (self.x_m + c * x_m - s * y_m, self.y_m + s * x_m + c * y_m)
            }

            /// A point given in the frame the pose is expressed in, in this pose's frame (the
            /// inverse of [`Self::transform_point`]).
            pub fn inverse_transform_point(&self, x_m: $t, y_m: $t) -> ($t, $t) {
                let (s, c) = $sin_cos(self.yaw_rad);
                let (dx, dy) = (x_m - self.x_m, y_m - self.y_m);
                (c * dx + s * dy, -s * dx + c * dy)
            }

            /// Distance between the positions (m); headings are ignored.
            pub fn distance_m(&self, other: &Self) -> $t {
                $hypot(self.x_m - other.x_m, self.y_m - other.y_m)
            }

            /// Whether every number is finite.
            pub fn is_finite(&self) -> bool {
                self.x_m.is_finite() && self.y_m.is_finite() && self.yaw_rad.is_finite()
            }

            /// Unicycle motion along a circular arc of length `ds_m` that turns by
            /// `dyaw_rad`, integrated exactly (the chord at the mid-arc heading; a straight
            /// line below 1e-6 rad of turn). The heading is wrapped into (-pi, pi].
            pub fn advance(&self, ds_m: $t, dyaw_rad: $t) -> Self {
                let chord = if dyaw_rad.abs() < 1e-6 {
                    ds_m
                } else {
                    2.0 * ds_m / dyaw_rad * $sin(dyaw_rad / 2.0)
                };
                let mid = self.yaw_rad + dyaw_rad / 2.0;
                Self {
                    x_m: self.x_m + chord * $cos(mid),
                    y_m: self.y_m + chord * $sin(mid),
                    yaw_rad: $wrap(self.yaw_rad + dyaw_rad),
                }
            }
        }
    };
}

pose_type!(
    /// A planar pose in f64: x, y (m), yaw (rad).
    Pose2,
    f64,
    wrap_angle,
    math::sin_cos,
    math::sin,
    math::cos,
    math::hypot
);
pose_type!(
    /// A planar pose in f32 (the firmware-like control laws): x, y (m), yaw (rad).
    Pose2F32,
    f32,
    wrap_angle_f32,
    math::sin_cos_f32,
    math::sin_f32,
    math::cos_f32,
    math::hypot_f32
);

impl Pose2 {
    /// The pose in f32 (rounded to nearest, each number on its own).
    pub fn to_f32(&self) -> Pose2F32 {
        Pose2F32::new(self.x_m as f32, self.y_m as f32, self.yaw_rad as f32)
    }
}

impl From<Pose2F32> for Pose2 {
    fn from(p: Pose2F32) -> Self {
        Self::new(f64::from(p.x_m), f64::from(p.y_m), f64::from(p.yaw_rad))
    }
}

#[cfg(test)]
mod tests;
