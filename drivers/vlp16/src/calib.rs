//! The sensor's geometry (laser elevations, vertical offsets, usable range) and its firing
//! timing (user manual 63-9243, sections 9.2 and 9.5).
//!
//! Frames: the sensor frame is right-handed, x forward (the sensor's 0 azimuth), y left, z up
//! (the ROS convention that `velodyne_pointcloud` and `velodyne-decoder` use). The packet's
//! azimuth `a` is clockwise seen from above, so a return at azimuth `a`, elevation `w` and
//! distance `d` from laser `l` with vertical offset `v` lies at
//! `x = d cos w cos a`, `y = -d cos w sin a`, `z = d sin w + v`: the laser's beam starts `v`
//! above the sensor origin (the manual's vertical correction, and what `velodyne-decoder` 3.1
//! does; the ROS driver's `vert_offset_correction` model, from the HDL-64E, puts the offset
//! perpendicular to the beam instead, which differs by `v sin w` horizontally: up to 2.9 mm on
//! the VLP-16).
//!
//! Azimuth interpolation: every firing's azimuth is the block's azimuth plus the rotation since
//! the block's first firing, at the packet's mean rate (the azimuth advance from its first to its
//! last firing cycle, over the cycles between). The block azimuths are whole hundredths of a
//! degree, so at 600 rpm the gaps between neighbouring blocks alternate between 39 and 40 for a
//! true 39.8: a gap to the next block would put up to 0.8 hundredths of error into the second
//! sequence, the packet's mean gap a tenth of that. `velodyne-decoder` 3.1 interpolates the same
//! way (the CI check compares every point).

use std::f64::consts::PI;

use crate::packet::{AZIMUTH_UNITS, BLOCKS, LASERS, ReturnMode};

/// Microseconds between two lasers' firings.
pub const LASER_PERIOD_US: f64 = 2.304;
/// Microseconds of one firing sequence of the 16 lasers and the recharge after it.
pub const SEQUENCE_PERIOD_US: f64 = 55.296;
/// Microseconds of a firing cycle (two sequences: one block in single-return mode).
pub const CYCLE_PERIOD_US: f64 = 2.0 * SEQUENCE_PERIOD_US;
/// Microseconds of a packet in single-return mode: 12 cycles (in dual-return mode a packet holds
/// 6 cycles, twice, and takes 663.552 us: twice the packets a second).
pub const PACKET_PERIOD_US: f64 = BLOCKS as f64 * CYCLE_PERIOD_US;
/// Packets a second in single-return mode (about 753.5; twice that in dual-return mode),
/// whatever the rotation rate.
pub const PACKETS_PER_S: f64 = 1e6 / PACKET_PERIOD_US;

/// The lasers' geometry and the usable range.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// Elevation of each laser id, degrees, positive up.
    pub elevation_deg: [f64; LASERS],
    /// Height of each laser's beam origin above the sensor origin, millimetres.
    pub vertical_offset_mm: [f64; LASERS],
    /// Returns nearer than this are dropped (the sensor's blind zone, and the robot's own body
    /// close around it).
    pub min_range_m: f64,
    /// Returns farther than this are dropped.
    pub max_range_m: f64,
}

/// A calibration that cannot be used, and why.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum CalibrationError {
    /// An elevation is not finite or not within +-90 degrees.
    #[error("laser {laser}: elevation {value} deg is not a finite angle within +-90 deg")]
    Elevation {
        /// The laser id.
        laser: usize,
        /// The value.
        value: f64,
    },
    /// A vertical offset is not finite or not within +-1 m.
    #[error("laser {laser}: vertical offset {value} mm is not finite or beyond +-1000 mm")]
    VerticalOffset {
        /// The laser id.
        laser: usize,
        /// The value.
        value: f64,
    },
    /// The range limits are not `0 <= min < max <= 200 m`.
    #[error("range limits {min_m} .. {max_m} m are not 0 <= min < max <= 200 m")]
    Range {
        /// `min_range_m`.
        min_m: f64,
        /// `max_range_m`.
        max_m: f64,
    },
}

impl Calibration {
    /// The VLP-16: elevations from the user manual (laser id 0..16: -15, +1, -13, +3, ... +15
    /// degrees); vertical offsets from Velodyne's VLP-16 calibration as the ROS driver ships it
    /// (`velodyne_pointcloud/params/VLP16db.yaml`, `vert_offset_correction`: 11.2, -0.7, 9.7 ...
    /// mm); range 0.5 m (the sensor's minimum) to 100 m (its rated range).
    pub const VLP16: Calibration = Calibration {
        elevation_deg: [
            -15.0, 1.0, -13.0, 3.0, -11.0, 5.0, -9.0, 7.0, -7.0, 9.0, -5.0, 11.0, -3.0, 13.0, -1.0,
            15.0,
        ],
        vertical_offset_mm: [
            11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1, 5.1, -6.6, 3.7, -8.1, 2.2, -9.7, 0.7,
            -11.2,
        ],
        min_range_m: 0.5,
        max_range_m: 100.0,
    };

    /// Checks every field; the first bad one is named.
    pub fn validate(&self) -> Result<(), CalibrationError> {
        for (laser, &value) in self.elevation_deg.iter().enumerate() {
            if !value.is_finite() || value.abs() > 90.0 {
                return Err(CalibrationError::Elevation { laser, value });
            }
        }
        for (laser, &value) in self.vertical_offset_mm.iter().enumerate() {
            if !value.is_finite() || value.abs() > 1000.0 {
                return Err(CalibrationError::VerticalOffset { laser, value });
            }
        }
        let (min_m, max_m) = (self.min_range_m, self.max_range_m);
        if !(min_m.is_finite()
            && max_m.is_finite()
            && min_m >= 0.0
            && min_m < max_m
            && max_m <= 200.0)
        {
            return Err(CalibrationError::Range { min_m, max_m });
        }
        Ok(())
    }

    /// The sines and cosines of the elevations and the offsets in metres, for conversions.
    pub fn trig(&self) -> LaserTrig {
        let mut t = LaserTrig {
            sin_w: [0.0; LASERS],
            cos_w: [0.0; LASERS],
            offset_m: [0.0; LASERS],
        };
        for l in 0..LASERS {
            let w = self.elevation_deg[l].to_radians();
            t.sin_w[l] = w.sin();
            t.cos_w[l] = w.cos();
            t.offset_m[l] = self.vertical_offset_mm[l] * 1e-3;
        }
        t
    }
}

/// Precomputed per-laser values of a [`Calibration`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserTrig {
    /// Sine of each laser's elevation.
    pub sin_w: [f64; LASERS],
    /// Cosine of each laser's elevation.
    pub cos_w: [f64; LASERS],
    /// Each laser's vertical offset, metres.
    pub offset_m: [f64; LASERS],
}

impl LaserTrig {
    /// A return in the sensor frame (module docs): laser, distance in metres, azimuth in
    /// hundredths of a degree (clockwise; any real value, not only 0..36000).
    pub fn sensor_point(&self, laser: usize, distance_m: f64, azimuth_cdeg: f64) -> [f64; 3] {
        let (sin_a, cos_a) = (azimuth_cdeg * (PI / 18_000.0)).sin_cos();
        self.sensor_point_sin_cos(laser, distance_m, sin_a, cos_a)
    }

    /// As [`Self::sensor_point`], with the azimuth's sine and cosine.
    pub fn sensor_point_sin_cos(
        &self,
        laser: usize,
        distance_m: f64,
        sin_a: f64,
        cos_a: f64,
    ) -> [f64; 3] {
        let l = laser % LASERS;
        let xy = distance_m * self.cos_w[l];
        [
            xy * cos_a,
            -xy * sin_a,
            distance_m * self.sin_w[l] + self.offset_m[l],
        ]
    }
}

/// Microseconds from a packet's timestamp (its first firing) to the firing of `laser` in
/// firing sequence `seq` (0 or 1) of `block`, in single-return mode:
/// `block * 110.592 + seq * 55.296 + laser * 2.304`.
pub fn firing_offset_us(block: usize, seq: usize, laser: usize) -> f64 {
    block as f64 * CYCLE_PERIOD_US
        + seq as f64 * SEQUENCE_PERIOD_US
        + laser as f64 * LASER_PERIOD_US
}

/// As [`firing_offset_us`] in any mode: in dual-return mode blocks `2k` and `2k + 1` hold the
/// same firing cycle `k`.
pub fn firing_offset_us_in(mode: ReturnMode, block: usize, seq: usize, laser: usize) -> f64 {
    firing_offset_us(block / mode.blocks_per_cycle(), seq, laser)
}

/// The azimuth advance (hundredths of a degree) over one firing cycle of a packet, from which
/// the azimuths of each block's later firings are interpolated: the advance from the first
/// cycle's azimuth to the last's (wrapping through 0), over the cycles between (11, or 5 in
/// dual-return mode). The same for every block of the packet (module docs say why).
pub fn cycle_gaps_cdeg(azimuths: &[u16; BLOCKS], mode: ReturnMode) -> [f64; BLOCKS] {
    let last = BLOCKS - mode.blocks_per_cycle();
    let cycles_between = (last / mode.blocks_per_cycle()) as f64;
    let advance =
        (i32::from(azimuths[last]) - i32::from(azimuths[0])).rem_euclid(i32::from(AZIMUTH_UNITS));
    [f64::from(advance) / cycles_between; BLOCKS]
}

/// The azimuth (hundredths of a degree, in `[0, 36000)`) of `laser`'s firing in sequence `seq`
/// of a block at `block_azimuth_cdeg` whose cycle advances `gap_cdeg`: the block's azimuth plus
/// the gap times the firing's share of the 110.592 us cycle.
pub fn firing_azimuth_cdeg(
    block_azimuth_cdeg: u16,
    gap_cdeg: f64,
    seq: usize,
    laser: usize,
) -> f64 {
    let share =
        (seq as f64 * SEQUENCE_PERIOD_US + laser as f64 * LASER_PERIOD_US) / CYCLE_PERIOD_US;
    (f64::from(block_azimuth_cdeg) + gap_cdeg * share).rem_euclid(f64::from(AZIMUTH_UNITS))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_bad_fields_are_named() {
        assert_eq!(Calibration::VLP16.validate(), Ok(()));
        let mut c = Calibration::VLP16;
        c.elevation_deg[3] = f64::NAN;
        assert!(matches!(
            c.validate(),
            Err(CalibrationError::Elevation { laser: 3, .. })
        ));
        let mut c = Calibration::VLP16;
        c.vertical_offset_mm[15] = 2000.0;
        assert!(matches!(
            c.validate(),
            Err(CalibrationError::VerticalOffset { laser: 15, .. })
        ));
        let mut c = Calibration::VLP16;
        c.min_range_m = 2.0;
        c.max_range_m = 1.0;
        assert!(c.validate().is_err());
    }

    #[test]
    fn timing_follows_the_manual() {
        assert_eq!(firing_offset_us(0, 0, 0), 0.0);
        assert!((firing_offset_us(0, 0, 15) - 34.56).abs() < 1e-9);
        assert!((firing_offset_us(0, 1, 0) - 55.296).abs() < 1e-9);
        assert!((firing_offset_us(11, 1, 15) - (11.0 * 110.592 + 55.296 + 34.56)).abs() < 1e-9);
        assert!((firing_offset_us_in(ReturnMode::Dual, 3, 0, 0) - 110.592).abs() < 1e-9);
        assert!((PACKETS_PER_S - 753.5).abs() < 0.1);
    }

    #[test]
    fn gaps_are_the_packets_mean_and_wrap() {
        // Gaps of 39 and 40 alternating: the mean, 39.5 (+ 0.5 / 11 from the last one).
        let mut az = [0u16; BLOCKS];
        for (k, a) in az.iter_mut().enumerate() {
            *a = ((35_800 + 40 * k - k / 2) % 36_000) as u16;
        }
        let gaps = cycle_gaps_cdeg(&az, ReturnMode::Strongest);
        let mean = f64::from((az[11] as i32 - az[0] as i32).rem_euclid(36_000)) / 11.0;
        assert!(
            gaps.iter().all(|&g| g == mean) && (mean - 39.545).abs() < 0.001,
            "{gaps:?}"
        );
        let mut dual = [0u16; BLOCKS];
        for (k, a) in dual.iter_mut().enumerate() {
            *a = ((35_950 + 40 * (k / 2)) % 36_000) as u16;
        }
        let gaps = cycle_gaps_cdeg(&dual, ReturnMode::Dual);
        assert!(gaps.iter().all(|&g| g == 40.0), "{gaps:?}");
        assert!((firing_azimuth_cdeg(35_990, 40.0, 1, 0) - 10.0).abs() < 1e-9);
    }
}
