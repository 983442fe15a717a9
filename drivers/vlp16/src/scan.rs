//! Revolutions of points in the base frame, cut where the azimuth passes 0, and deskewing.
//!
//! Each return's azimuth is interpolated to its own firing: the block's azimuth plus the
//! cycle's azimuth advance times the firing's share of the 110.592 us cycle
//! ([`crate::calib::firing_azimuth_cdeg`]); its time is the packet's timestamp, unwrapped by the
//! [`HourClock`], plus [`crate::calib::firing_offset_us_in`].

use crate::calib::{
    Calibration, CalibrationError, LaserTrig, cycle_gaps_cdeg, firing_azimuth_cdeg,
    firing_offset_us_in,
};
use crate::health::{ClockStep, HourClock};
use crate::packet::{AZIMUTH_UNITS, BLOCKS, DataPacket, LASERS, Return};
use crate::{BlindSector, Mount, MountError};

const CDEG_TO_RAD: f64 = std::f64::consts::PI / 18_000.0;

/// One return in the base frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Point {
    /// Base frame, metres.
    pub x: f32,
    /// Base frame, metres.
    pub y: f32,
    /// Base frame, metres.
    pub z: f32,
    /// Time of the firing, microseconds on the sensor's unwrapped hour clock
    /// ([`HourClock`]).
    pub t_us: i64,
    /// Calibrated reflectivity.
    pub intensity: u8,
    /// Laser id (0..16).
    pub laser: u8,
}

/// Returns dropped, by reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DropCounts {
    /// Distance 0: no return.
    pub no_return: u64,
    /// Nearer than the calibration's minimum range.
    pub below_min_range: u64,
    /// Farther than its maximum range.
    pub beyond_max_range: u64,
    /// In a blind sector.
    pub blind: u64,
    /// The second return of a dual-return cycle equal to the first.
    pub duplicate: u64,
    /// No room left in the revolution's buffer (its capacity).
    pub overflow: u64,
}

impl DropCounts {
    /// All dropped returns.
    pub fn total(&self) -> u64 {
        self.no_return
            + self.below_min_range
            + self.beyond_max_range
            + self.blind
            + self.duplicate
            + self.overflow
    }
}

/// A completed revolution; its points are [`ScanAssembler::points`] until the next one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanDone {
    /// Points kept.
    pub points: usize,
    /// Returns dropped, by reason.
    pub dropped: DropCounts,
    /// Packets that contributed returns.
    pub packets: u32,
    /// Firing time of the revolution's first return, unwrapped microseconds.
    pub start_us: i64,
    /// Firing time of its last return.
    pub end_us: i64,
    /// Host arrival time of the packet that completed it.
    pub arrival_ns: u64,
    /// Whether the revolution began where the previous one ended (false for the first, partial
    /// one after start-up).
    pub complete: bool,
}

/// Revolutions of points.
#[derive(Debug, Clone)]
pub struct ScanAssembler {
    trig: LaserTrig,
    calib: Calibration,
    mount: Mount,
    mount_yaw_sin_cos: (f64, f64),
    blind: Vec<BlindSector>,
    filling: Vec<Point>,
    done: Vec<Point>,
    capacity: usize,
    clock: HourClock,
    dropped: DropCounts,
    packets: u32,
    start_us: Option<i64>,
    end_us: i64,
    begun_at_wrap: bool,
    last_azimuth_cdeg: Option<f64>,
    last_done: Option<ScanDone>,
    /// Revolutions that completed and were replaced within the same packet (malformed input).
    pub overwritten: u64,
}

/// A scan assembler that cannot be made, and why.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ScanConfigError {
    /// The calibration is invalid.
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    /// The mount or a blind sector is invalid.
    #[error(transparent)]
    Mount(#[from] MountError),
}

impl ScanAssembler {
    /// An assembler holding up to `capacity` points a revolution (a VLP-16 at 600 rpm gives
    /// about 28,800 returns a revolution in single-return mode; 30,000 leaves room). All
    /// allocation happens here.
    pub fn new(
        calib: Calibration,
        mount: Mount,
        blind: &[BlindSector],
        capacity: usize,
    ) -> Result<Self, ScanConfigError> {
        calib.validate()?;
        mount.validate()?;
        for (index, b) in blind.iter().enumerate() {
            b.validate(index)?;
        }
        Ok(Self {
            trig: calib.trig(),
            calib,
            mount,
            mount_yaw_sin_cos: mount.yaw_rad.sin_cos(),
            blind: blind.to_vec(),
            filling: Vec::with_capacity(capacity),
            done: Vec::with_capacity(capacity),
            capacity,
            clock: HourClock::new(),
            dropped: DropCounts::default(),
            packets: 0,
            start_us: None,
            end_us: 0,
            begun_at_wrap: false,
            last_azimuth_cdeg: None,
            last_done: None,
            overwritten: 0,
        })
    }

    /// The points of the last completed revolution, base frame, in firing order.
    pub fn points(&self) -> &[Point] {
        &self.done
    }

    /// The last completed revolution's summary.
    pub fn last_done(&self) -> Option<ScanDone> {
        self.last_done
    }

    /// The calibration in use.
    pub fn calibration(&self) -> &Calibration {
        &self.calib
    }

    /// The mount in use.
    pub fn mount(&self) -> &Mount {
        &self.mount
    }

    fn finish(&mut self, arrival_ns: u64, at_wrap: bool) -> Option<ScanDone> {
        let start_us = self.start_us?;
        let done = ScanDone {
            points: self.filling.len(),
            dropped: self.dropped,
            packets: self.packets,
            start_us,
            end_us: self.end_us,
            arrival_ns,
            complete: self.begun_at_wrap,
        };
        std::mem::swap(&mut self.filling, &mut self.done);
        self.filling.clear();
        self.dropped = DropCounts::default();
        self.packets = 0;
        self.start_us = None;
        self.begun_at_wrap = at_wrap;
        self.last_done = Some(done);
        Some(done)
    }

    /// Adds a packet's returns; when the azimuth passed 0 in it, the revolution before is
    /// complete and returned (its points in [`Self::points`]). Returns of a reordered packet
    /// (its timestamp before the newest seen) are kept in the revolution being filled.
    pub fn push(&mut self, packet: &DataPacket, arrival_ns: u64) -> Option<ScanDone> {
        let tick = self.clock.tick(packet.timestamp_us, arrival_ns);
        let mode = packet.return_mode;
        let step = mode.blocks_per_cycle();
        let azimuths = packet.blocks.map(|b| b.azimuth_cdeg);
        let gaps = cycle_gaps_cdeg(&azimuths, mode);
        // Every firing's azimuth is its block's plus a per-firing advance, the same in every
        // block of the packet (one gap per packet): the sines and cosines come from one
        // `sin_cos` per block and per firing slot by angle addition, not one per return.
        let mut advance = [[(0.0, 1.0); LASERS]; 2];
        for (seq, slots) in advance.iter_mut().enumerate() {
            for (laser, slot) in slots.iter_mut().enumerate() {
                let cdeg = firing_azimuth_cdeg(0, gaps[0], seq, laser);
                *slot = (cdeg * CDEG_TO_RAD).sin_cos();
            }
        }
        let mut completed: Option<ScanDone> = None;
        let mut contributed = false;
        for cycle in (0..BLOCKS).step_by(step) {
            let (sin_block, cos_block) = (f64::from(azimuths[cycle]) * CDEG_TO_RAD).sin_cos();
            for (seq, slots) in advance.iter().enumerate() {
                let first_azimuth = firing_azimuth_cdeg(azimuths[cycle], gaps[cycle], seq, 0);
                // The revolution ends where the azimuth passes 0: a drop of more than half a
                // turn from the firing before (a reordered packet only steps back a little).
                if tick.step != ClockStep::Backwards
                    && let Some(last) = self.last_azimuth_cdeg
                    && first_azimuth < last - f64::from(AZIMUTH_UNITS / 2)
                {
                    if let Some(done) = self.finish(arrival_ns, true) {
                        if completed.replace(done).is_some() {
                            self.overwritten += 1;
                        }
                        contributed = false;
                    } else {
                        self.begun_at_wrap = true;
                    }
                }
                if tick.step != ClockStep::Backwards {
                    self.last_azimuth_cdeg = Some(first_azimuth);
                }
                for (laser, &(sin_d, cos_d)) in slots.iter().enumerate() {
                    let azimuth = firing_azimuth_cdeg(azimuths[cycle], gaps[cycle], seq, laser);
                    let sin_cos = (
                        sin_block * cos_d + cos_block * sin_d,
                        cos_block * cos_d - sin_block * sin_d,
                    );
                    let t_us =
                        tick.t_us + firing_offset_us_in(mode, cycle, seq, laser).round() as i64;
                    for b in cycle..cycle + step {
                        let ret = packet.blocks[b].returns[seq * LASERS + laser];
                        if b > cycle && ret == packet.blocks[cycle].returns[seq * LASERS + laser] {
                            self.dropped.duplicate += 1;
                            continue;
                        }
                        self.add(ret, laser, azimuth, sin_cos, t_us);
                        contributed = true;
                    }
                }
            }
        }
        if contributed {
            self.packets = self.packets.saturating_add(1);
        }
        completed
    }

    fn add(
        &mut self,
        ret: Return,
        laser: usize,
        azimuth_cdeg: f64,
        azimuth_sin_cos: (f64, f64),
        t_us: i64,
    ) {
        if self.start_us.is_none() {
            self.start_us = Some(t_us);
        }
        self.end_us = self.end_us.max(t_us);
        if ret.distance_2mm == 0 {
            self.dropped.no_return += 1;
            return;
        }
        let d = ret.distance_m();
        if d < self.calib.min_range_m {
            self.dropped.below_min_range += 1;
            return;
        }
        if d > self.calib.max_range_m {
            self.dropped.beyond_max_range += 1;
            return;
        }
        if !self.blind.is_empty() {
            // Direction in the sensor frame, counterclockwise from x: minus the azimuth.
            let direction_deg = -azimuth_cdeg / 100.0;
            if self.blind.iter().any(|b| b.contains_deg(direction_deg)) {
                self.dropped.blind += 1;
                return;
            }
        }
        if self.filling.len() >= self.capacity {
            self.dropped.overflow += 1;
            return;
        }
        let sensor = self
            .trig
            .sensor_point_sin_cos(laser, d, azimuth_sin_cos.0, azimuth_sin_cos.1);
        let (sy, cy) = self.mount_yaw_sin_cos;
        let p = [
            self.mount.x_m + cy * sensor[0] - sy * sensor[1],
            self.mount.y_m + sy * sensor[0] + cy * sensor[1],
            self.mount.z_m + sensor[2],
        ];
        self.filling.push(Point {
            x: p[0] as f32,
            y: p[1] as f32,
            z: p[2] as f32,
            t_us,
            intensity: ret.reflectivity,
            laser: laser as u8,
        });
    }
}

/// Every return of one packet, in the sensor frame, no return dropped but those of distance 0:
/// `(block, seq, laser, [x, y, z], azimuth_cdeg)`, in packet order. For tools and checks (the
/// third-party comparison in `.ci/vlp16-decoder-check.sh`); the robot uses [`ScanAssembler`].
pub fn packet_points(
    packet: &DataPacket,
    trig: &LaserTrig,
    mut f: impl FnMut(usize, usize, usize, [f64; 3], f64),
) {
    let azimuths = packet.blocks.map(|b| b.azimuth_cdeg);
    let gaps = cycle_gaps_cdeg(&azimuths, packet.return_mode);
    for (b, block) in packet.blocks.iter().enumerate() {
        for seq in 0..2 {
            for laser in 0..LASERS {
                let ret = block.returns[seq * LASERS + laser];
                if ret.distance_2mm == 0 {
                    continue;
                }
                let azimuth = firing_azimuth_cdeg(azimuths[b], gaps[b], seq, laser);
                f(
                    b,
                    seq,
                    laser,
                    trig.sensor_point(laser, ret.distance_m(), azimuth),
                    azimuth,
                );
            }
        }
    }
}

/// Moves each point (base frame at its firing time `t_us`) into the base frame at `t_ref_us`,
/// for a base moving at constant forward speed `v_mps` and yaw rate `w_radps` (a unicycle) over
/// the revolution. The points' `t_us` stay their firing times.
pub fn deskew(points: &mut [Point], v_mps: f64, w_radps: f64, t_ref_us: i64) {
    for p in points {
        let dt = (p.t_us - t_ref_us) as f64 * 1e-6;
        let th = w_radps * dt;
        // The base's pose at the firing, in the base frame at t_ref.
        let (tx, ty) = if (w_radps * dt).abs() < 1e-9 {
            (v_mps * dt, 0.5 * v_mps * w_radps * dt * dt)
        } else {
            (
                v_mps / w_radps * th.sin(),
                v_mps / w_radps * (1.0 - th.cos()),
            )
        };
        let (s, c) = th.sin_cos();
        let (x, y) = (f64::from(p.x), f64::from(p.y));
        p.x = (tx + c * x - s * y) as f32;
        p.y = (ty + s * x + c * y) as f32;
    }
}
