//! The sensor's firing schedule, for a simulator: which ray each laser fires when, and the data
//! packets the sensor would send, spread over the revolution exactly as the real sensor's timing
//! (one laser every 2.304 us, a sequence every 55.296 us, a packet every 1.327 ms in
//! single-return mode: 753.5 packets a second at any rotation rate; twice that in dual-return
//! mode, whose packets hold 6 firing cycles).
//!
//! The world casts each ray at its firing instant ([`Firing`]), from wherever the moving base
//! is then, so a revolution is skewed by the base's motion as a real one is.

use std::f64::consts::PI;

use crate::calib::{
    CYCLE_PERIOD_US, Calibration, CalibrationError, LASER_PERIOD_US, SEQUENCE_PERIOD_US,
};
use crate::packet::{
    AZIMUTH_UNITS, BLOCKS, Block, DISTANCE_UNIT_M, DataPacket, HOUR_US, LASERS, PAYLOAD_LEN,
    PRODUCT_ID_VLP16, RETURNS_PER_BLOCK, Return, ReturnMode,
};

/// One laser firing: the ray the world casts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Firing {
    /// When it fires, microseconds on the simulation's clock (rounded to the microsecond).
    pub t_us: u64,
    /// The ray's direction in the sensor frame, radians counterclockwise from the sensor's x
    /// axis seen from above (in (-pi, pi]); the sensor reports the clockwise azimuth, minus this.
    pub azimuth_rad: f64,
    /// The ray's elevation, radians, positive up.
    pub elevation_rad: f64,
    /// The ray starts this far above the sensor origin, metres ([`Self::origin`]).
    pub vertical_offset_m: f64,
    /// Laser id (0..16).
    pub laser: u8,
}

impl Firing {
    /// The ray's origin in the sensor frame: the decoder places a return at
    /// `origin() + range * direction()` (`crate::calib`).
    pub fn origin(&self) -> [f64; 3] {
        [0.0, 0.0, self.vertical_offset_m]
    }

    /// The ray's unit direction in the sensor frame.
    pub fn direction(&self) -> [f64; 3] {
        let (sw, cw) = self.elevation_rad.sin_cos();
        let (sa, ca) = self.azimuth_rad.sin_cos();
        [cw * ca, cw * sa, sw]
    }
}

/// An emitter that cannot be made, and why.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum SimError {
    /// The rotation rate is not within the sensor's 300-1200 rpm.
    #[error("rotation rate {rpm} rpm is not within the VLP-16's 300-1200 rpm")]
    Rpm {
        /// The rate asked for.
        rpm: f64,
    },
    /// The calibration is invalid.
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
}

/// The simulated sensor's packet stream.
#[derive(Debug, Clone)]
pub struct Emitter {
    calib: Calibration,
    mode: ReturnMode,
    start_us: u64,
    start_azimuth_cdeg: f64,
    cdeg_per_us: f64,
    next_packet: u64,
    product_id: u8,
}

impl Emitter {
    /// A sensor turning at `rpm` (300-1200), its first packet's first firing at `start_us` on
    /// the simulation's clock (which is also the sensor's clock: the packet timestamp is it
    /// modulo the hour), facing azimuth 0 then.
    pub fn new(
        rpm: f64,
        return_mode: ReturnMode,
        calib: Calibration,
        start_us: u64,
    ) -> Result<Self, SimError> {
        if !(300.0..=1200.0).contains(&rpm) {
            return Err(SimError::Rpm { rpm });
        }
        calib.validate()?;
        Ok(Self {
            calib,
            mode: return_mode,
            start_us,
            start_azimuth_cdeg: 0.0,
            cdeg_per_us: rpm * f64::from(AZIMUTH_UNITS) / 60e6,
            next_packet: 0,
            product_id: PRODUCT_ID_VLP16,
        })
    }

    /// The same, facing `azimuth_deg` (clockwise, the sensor's convention) at `start_us`.
    pub fn with_start_azimuth_deg(mut self, azimuth_deg: f64) -> Self {
        if azimuth_deg.is_finite() {
            self.start_azimuth_cdeg = (azimuth_deg * 100.0).rem_euclid(f64::from(AZIMUTH_UNITS));
        }
        self
    }

    /// The same, sending another product id (to test the health check).
    pub fn with_product_id(mut self, product_id: u8) -> Self {
        self.product_id = product_id;
        self
    }

    /// Microseconds a packet covers: 12 cycles, or 6 in dual-return mode.
    pub fn packet_period_us(&self) -> f64 {
        (BLOCKS / self.mode.blocks_per_cycle()) as f64 * CYCLE_PERIOD_US
    }

    /// Packets sent so far.
    pub fn packets_sent(&self) -> u64 {
        self.next_packet
    }

    /// Time of packet `k`'s first firing, microseconds (fractional) after `start_us` (relative,
    /// so that an epoch-sized `start_us` costs no precision).
    fn packet_start_us(&self, k: u64) -> f64 {
        k as f64 * self.packet_period_us()
    }

    /// A relative time as a time on the simulation's clock, rounded to the microsecond.
    fn absolute_us(&self, relative_us: f64) -> u64 {
        self.start_us.saturating_add(relative_us.round() as u64)
    }

    /// Offset of the last firing of a packet from its first.
    fn last_firing_offset_us(&self) -> f64 {
        self.packet_period_us() - CYCLE_PERIOD_US
            + SEQUENCE_PERIOD_US
            + (LASERS - 1) as f64 * LASER_PERIOD_US
    }

    /// The time of the next packet's last firing (when [`Self::emit_until`] will send it).
    pub fn next_packet_time_us(&self) -> u64 {
        self.absolute_us(self.packet_start_us(self.next_packet) + self.last_firing_offset_us())
    }

    /// The true azimuth (hundredths of a degree, clockwise, unwrapped) `relative_us` after
    /// `start_us`.
    fn azimuth_cdeg_at(&self, relative_us: f64) -> f64 {
        self.start_azimuth_cdeg + self.cdeg_per_us * relative_us
    }

    /// Sends every packet whose last firing is at or before `t_us`: for each firing, in time
    /// order, asks `cast` for the range (metres) and reflectivity of the ray (`None`: no return),
    /// quantises the range to 2 mm (beyond 131 m: no return), and hands each finished packet to
    /// `out` with the time of its last firing.
    pub fn emit_until(
        &mut self,
        t_us: u64,
        cast: &mut dyn FnMut(Firing) -> Option<(f64, u8)>,
        out: &mut dyn FnMut(&[u8; PAYLOAD_LEN], u64),
    ) {
        let mut bytes = [0u8; PAYLOAD_LEN];
        while self.next_packet_time_us() <= t_us {
            let sent_at = self.next_packet_time_us();
            let packet = self.build(self.next_packet, cast);
            packet.encode(&mut bytes);
            out(&bytes, sent_at);
            self.next_packet += 1;
        }
    }

    fn build(&self, k: u64, cast: &mut dyn FnMut(Firing) -> Option<(f64, u8)>) -> DataPacket {
        let start = self.packet_start_us(k);
        let step = self.mode.blocks_per_cycle();
        let empty = Block {
            azimuth_cdeg: 0,
            returns: [Return::default(); RETURNS_PER_BLOCK],
        };
        let mut blocks = [empty; BLOCKS];
        for cycle in 0..BLOCKS / step {
            let cycle_start = start + cycle as f64 * CYCLE_PERIOD_US;
            let encoder = self
                .azimuth_cdeg_at(cycle_start)
                .round()
                .rem_euclid(f64::from(AZIMUTH_UNITS));
            let mut returns = [Return::default(); RETURNS_PER_BLOCK];
            for seq in 0..2 {
                for laser in 0..LASERS {
                    let t = cycle_start
                        + seq as f64 * SEQUENCE_PERIOD_US
                        + laser as f64 * LASER_PERIOD_US;
                    let clockwise_rad = self.azimuth_cdeg_at(t) * (PI / 18_000.0);
                    let azimuth_rad = planar::wrap_angle(-clockwise_rad);
                    let firing = Firing {
                        t_us: self.absolute_us(t),
                        azimuth_rad,
                        elevation_rad: self.calib.elevation_deg[laser].to_radians(),
                        vertical_offset_m: self.calib.vertical_offset_mm[laser] * 1e-3,
                        laser: laser as u8,
                    };
                    returns[seq * LASERS + laser] = match cast(firing) {
                        Some((range_m, reflectivity)) if range_m.is_finite() && range_m > 0.0 => {
                            let units = (range_m / DISTANCE_UNIT_M).round();
                            if units <= f64::from(u16::MAX) {
                                Return {
                                    distance_2mm: units as u16,
                                    reflectivity,
                                }
                            } else {
                                Return::default()
                            }
                        }
                        _ => Return::default(),
                    };
                }
            }
            for block in blocks.iter_mut().skip(cycle * step).take(step) {
                *block = Block {
                    azimuth_cdeg: encoder as u16 % AZIMUTH_UNITS,
                    returns,
                };
            }
        }
        DataPacket {
            blocks,
            timestamp_us: (self.absolute_us(start) % u64::from(HOUR_US)) as u32,
            return_mode: self.mode,
            product_id: self.product_id,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn firing_directions_are_unit_and_in_range() {
        let mut e = Emitter::new(600.0, ReturnMode::Strongest, Calibration::VLP16, 0)
            .unwrap_or_else(|err| panic!("{err}"));
        let mut seen = 0;
        e.emit_until(
            100_000,
            &mut |f| {
                let d = f.direction();
                assert!(((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - 1.0).abs() < 1e-12);
                assert!(
                    f.azimuth_rad > -PI - 1e-12 && f.azimuth_rad <= PI + 1e-12,
                    "{f:?}"
                );
                seen += 1;
                None
            },
            &mut |_, _| {},
        );
        assert_eq!(seen, e.packets_sent() * 384);
        assert!(Emitter::new(100.0, ReturnMode::Strongest, Calibration::VLP16, 0).is_err());
    }
}
