//! Velodyne VLP-16 driver: the sensor's UDP data packets decoded into points in the robot's base
//! frame, the sensor's health (packet rate, rotation rate, product id, the hour clock), and the
//! sensor's firing schedule for a simulator. No other grop crate is needed; docs/lidar.md has the
//! packet format, the frames, the timing and the health thresholds.
//!
//! ```no_run
//! use vlp16::{BlindSector, Mount, calib::Calibration, health::{Health, HealthConfig}};
//! use vlp16::{scan::ScanAssembler, udp::UdpSource};
//!
//! let mount = Mount { x_m: 0.2, y_m: 0.0, z_m: 0.45, yaw_rad: 0.0 };
//! let blind = [BlindSector { from_deg: 160.0, to_deg: 200.0 }];
//! let mut scans = ScanAssembler::new(Calibration::VLP16, mount, &blind, 30_000)?;
//! let mut health = Health::new(HealthConfig::default());
//! let mut source = UdpSource::bind(("0.0.0.0", vlp16::packet::DATA_PORT))?;
//! let now_ns = 0; // the host clock
//! source.drain(|packet| match packet {
//!     Ok(p) => {
//!         health.on_packet(&p, now_ns);
//!         if let Some(done) = scans.push(&p, now_ns) {
//!             let _points = scans.points(); // one revolution, base frame
//!             let _ = done;
//!         }
//!     }
//!     Err(e) => health.on_error(&e, now_ns),
//! })?;
//! let _usable = health.verdict(now_ns).is_ok();
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod calib;
pub mod health;
pub mod packet;
pub mod pcap;
pub mod scan;
pub mod sim;
pub mod udp;

pub use packet::{DataPacket, PacketError, ReturnMode};

/// Where the sensor sits on the robot: the sensor frame (x forward at azimuth 0, y left, z up)
/// in the base frame, by its origin and its yaw about the base's z axis (the sensor is mounted
/// level).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mount {
    /// Sensor origin in the base frame, metres.
    pub x_m: f64,
    /// Sensor origin in the base frame, metres.
    pub y_m: f64,
    /// Sensor origin above the base frame's origin, metres.
    pub z_m: f64,
    /// Yaw of the sensor frame in the base frame, radians (counterclockwise seen from above).
    pub yaw_rad: f64,
}

/// A mount that is not a pose, and why.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum MountError {
    /// A field is not finite.
    #[error("lidar mount: {field} = {value} is not a finite number")]
    NotFinite {
        /// The field's name.
        field: &'static str,
        /// The value.
        value: f64,
    },
    /// A blind sector is not `-360 <= from_deg <= 360`, `0 < to_deg - from_deg <= 360`.
    #[error(
        "blind sector {index}: {from_deg} .. {to_deg} deg is not -360 <= from <= 360, 0 < to - from <= 360"
    )]
    BlindSector {
        /// The sector's index.
        index: usize,
        /// `from_deg`.
        from_deg: f64,
        /// `to_deg`.
        to_deg: f64,
    },
}

impl Mount {
    /// The sensor at the base's origin, unrotated.
    pub const IDENTITY: Mount = Mount {
        x_m: 0.0,
        y_m: 0.0,
        z_m: 0.0,
        yaw_rad: 0.0,
    };

    /// Checks that every field is finite.
    pub fn validate(&self) -> Result<(), MountError> {
        for (field, value) in [
            ("x_m", self.x_m),
            ("y_m", self.y_m),
            ("z_m", self.z_m),
            ("yaw_rad", self.yaw_rad),
        ] {
            if !value.is_finite() {
                return Err(MountError::NotFinite { field, value });
            }
        }
        Ok(())
    }

    /// A sensor-frame point in the base frame.
    pub fn to_base(&self, p: [f64; 3]) -> [f64; 3] {
        let (s, c) = self.yaw_rad.sin_cos();
        [
            self.x_m + c * p[0] - s * p[1],
            self.y_m + s * p[0] + c * p[1],
            self.z_m + p[2],
        ]
    }
}

/// A sector of the sensor frame the sensor cannot usefully see (the arm's column behind it, a
/// mast): returns there are dropped and counted. Angles are the direction of the point in the
/// sensor frame, counterclockwise from its x axis seen from above (`atan2(y, x)`), in degrees;
/// the sector runs counterclockwise from `from_deg` to `to_deg` (`{ from_deg: 160, to_deg: 200 }`
/// is the 40 degrees straight behind the sensor; `{ from_deg: -20, to_deg: 20 }` the 40 degrees
/// ahead).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BlindSector {
    /// Where the sector starts, degrees counterclockwise from the sensor's x axis.
    pub from_deg: f64,
    /// Where it ends (`from_deg < to_deg <= from_deg + 360`).
    pub to_deg: f64,
}

impl BlindSector {
    /// Checks the bounds (see [`MountError::BlindSector`]); `index` names the sector.
    pub fn validate(&self, index: usize) -> Result<(), MountError> {
        let width = self.to_deg - self.from_deg;
        let ok = self.from_deg.is_finite()
            && self.to_deg.is_finite()
            && (-360.0..=360.0).contains(&self.from_deg)
            && width > 0.0
            && width <= 360.0;
        if ok {
            Ok(())
        } else {
            Err(MountError::BlindSector {
                index,
                from_deg: self.from_deg,
                to_deg: self.to_deg,
            })
        }
    }

    /// Whether a direction (degrees counterclockwise from the sensor's x axis, any real value)
    /// lies in the sector.
    pub fn contains_deg(&self, angle_deg: f64) -> bool {
        let width = self.to_deg - self.from_deg;
        if width >= 360.0 {
            return true;
        }
        (angle_deg - self.from_deg).rem_euclid(360.0) < width
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mount_moves_and_turns_points() {
        let m = Mount {
            x_m: 1.0,
            y_m: 2.0,
            z_m: 0.5,
            yaw_rad: std::f64::consts::FRAC_PI_2,
        };
        let p = m.to_base([1.0, 0.0, 0.25]);
        assert!((p[0] - 1.0).abs() < 1e-12 && (p[1] - 3.0).abs() < 1e-12 && p[2] == 0.75);
        assert!(m.validate().is_ok());
        let bad = Mount { x_m: f64::NAN, ..m };
        assert_eq!(
            bad.validate().map_err(|e| e.to_string().contains("x_m")),
            Err(true)
        );
    }

    #[test]
    fn blind_sectors_cross_zero() {
        let ahead = BlindSector {
            from_deg: -20.0,
            to_deg: 20.0,
        };
        assert!(ahead.contains_deg(0.0) && ahead.contains_deg(350.0) && ahead.contains_deg(-10.0));
        assert!(!ahead.contains_deg(30.0) && !ahead.contains_deg(180.0));
        assert!(ahead.validate(0).is_ok());
        assert!(
            BlindSector {
                from_deg: 10.0,
                to_deg: 10.0
            }
            .validate(2)
            .is_err()
        );
        assert!(
            BlindSector {
                from_deg: 0.0,
                to_deg: 400.0
            }
            .validate(2)
            .is_err()
        );
    }

    #[test]
    fn mount_file_rejects_unknown_fields() {
        let ok: Result<Mount, _> = toml::from_str("x_m = 0.1\ny_m = 0.0\nz_m = 0.4\nyaw_rad = 0.0");
        assert!(ok.is_ok());
        let typo: Result<Mount, _> =
            toml::from_str("x_m = 0.1\ny_m = 0.0\nz_m = 0.4\nyaw_rad = 0.0\nyaw_deg = 3");
        assert!(typo.is_err());
    }
}
