//! The sensor's health: is the point stream fresh and from a VLP-16 turning at its configured
//! rate? A sensor that is not ([`SensorVerdict::Stale`] or [`SensorVerdict::OutOfSpec`]) counts
//! as a stale scan for every consumer.
//!
//! Thresholds (the defaults of [`HealthConfig`], docs/lidar.md):
//! - stale: no data packet for more than 100 ms (the sensor sends one every 1.33 ms);
//! - out of spec: the newest packet's product id is not 0x22 (VLP-16);
//! - out of spec: the rotation rate, measured from the azimuth advance over the packets'
//!   timestamps in the last 250 ms window, is outside the configured rate +-10 %, or not yet
//!   measured (fewer than 20 packet pairs);
//! - out of spec: fewer than 600 packets a second over the last full window (nominal 753.5 in
//!   single-return mode, 1507 in dual: the sensor is losing packets, or the link is).
//!
//! Malformed, wrong-length and reordered packets are counted and the last one named; they do not
//! change the verdict by themselves (the good packets between them keep the stream fresh).

use std::time::Duration;

use crate::calib::PACKETS_PER_S;
use crate::packet::{
    AZIMUTH_UNITS, DataPacket, HOUR_US, PRODUCT_ID_VLP16, PacketError, ReturnMode,
};

const HOUR_US_I64: i64 = HOUR_US as i64;

/// How a timestamp moved the hour clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClockStep {
    /// The first timestamp seen.
    First,
    /// Later than every earlier one, in the same hour.
    Forward,
    /// Later than every earlier one, past the top of the hour (3,599,999,xxx -> small).
    Wrapped,
    /// Not later than the newest seen: a reordered (or repeated) packet.
    Backwards,
}

/// A timestamp placed on the unwrapped clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tick {
    /// Microseconds on the unwrapped sensor clock (hours since the first packet's hour times
    /// 3.6e9, plus the timestamp).
    pub t_us: i64,
    /// How it moved the clock.
    pub step: ClockStep,
}

/// Ties the packet timestamp (microseconds past the hour) to a monotonic microsecond count and
/// to the host clock. Each timestamp is placed in the hour (this one, the next or the previous)
/// that puts it nearest to the newest timestamp seen, so the hourly wrap reads as 1.33 ms of
/// progress, not as a jump back; a packet from just before the wrap that arrives after it is
/// placed before the wrap (reordered), not an hour ahead.
///
/// The host offset (host ns minus sensor ns) is the smallest seen over the last one to two
/// seconds of arrivals: network and scheduling delays only ever add to it, and the window lets
/// it follow the two clocks' drift.
#[derive(Debug, Clone, Copy, Default)]
pub struct HourClock {
    newest_us: Option<i64>,
    offset_now: Option<i64>,
    offset_before: Option<i64>,
    offset_bucket_start_ns: u64,
}

fn min_opt(a: Option<i64>, b: Option<i64>) -> Option<i64> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, None) => a,
        (None, b) => b,
    }
}

impl HourClock {
    /// A clock that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// Places a timestamp (any `u32`; values of an hour or more are taken modulo the hour) that
    /// arrived at `arrival_ns` on the host clock.
    pub fn tick(&mut self, timestamp_us: u32, arrival_ns: u64) -> Tick {
        let toh = i64::from(timestamp_us % HOUR_US);
        let tick = match self.newest_us {
            None => {
                self.newest_us = Some(toh);
                Tick {
                    t_us: toh,
                    step: ClockStep::First,
                }
            }
            Some(newest) => {
                let hour = newest.div_euclid(HOUR_US_I64);
                let candidates = [hour - 1, hour, hour + 1].map(|h| h * HOUR_US_I64 + toh);
                let mut t = candidates[1];
                for c in candidates {
                    if (c - newest).abs() < (t - newest).abs() {
                        t = c;
                    }
                }
                let step = if t <= newest {
                    ClockStep::Backwards
                } else if t.div_euclid(HOUR_US_I64) > hour {
                    ClockStep::Wrapped
                } else {
                    ClockStep::Forward
                };
                if t > newest {
                    self.newest_us = Some(t);
                }
                Tick { t_us: t, step }
            }
        };
        // Host offset, from forward packets only (a reordered one was delayed anyway).
        if tick.step != ClockStep::Backwards {
            let host = i64::try_from(arrival_ns).unwrap_or(i64::MAX);
            let offset = host.saturating_sub(tick.t_us.saturating_mul(1000));
            if arrival_ns.saturating_sub(self.offset_bucket_start_ns) >= 1_000_000_000
                || self.offset_now.is_none()
            {
                self.offset_before = self.offset_now;
                self.offset_now = None;
                self.offset_bucket_start_ns = arrival_ns;
            }
            self.offset_now = min_opt(self.offset_now, Some(offset));
        }
        tick
    }

    /// The newest timestamp on the unwrapped clock.
    pub fn newest_us(&self) -> Option<i64> {
        self.newest_us
    }

    /// Host nanoseconds minus sensor nanoseconds, once a timestamp has been seen.
    pub fn host_offset_ns(&self) -> Option<i64> {
        min_opt(self.offset_now, self.offset_before)
    }

    /// A time on the unwrapped sensor clock as host nanoseconds.
    pub fn host_ns(&self, t_us: i64) -> Option<i64> {
        self.host_offset_ns()
            .map(|o| t_us.saturating_mul(1000).saturating_add(o))
    }
}

/// The thresholds of [`Health::verdict`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HealthConfig {
    /// The rotation rate the sensor is configured for (300-1200 rpm).
    pub nominal_rpm: f64,
    /// Allowed relative deviation of the measured rate (0.10: +-10 %).
    pub rpm_tolerance: f64,
    /// No packet for longer than this: stale.
    pub stale_after_ns: u64,
    /// The measuring window of the packet and rotation rates.
    pub window_ns: u64,
    /// Fewer packets a second than this over a full window: out of spec.
    pub min_packet_rate_hz: f64,
    /// Packet pairs needed before the rotation rate counts as measured.
    pub min_rpm_pairs: u32,
}

impl Default for HealthConfig {
    fn default() -> Self {
        Self {
            nominal_rpm: 600.0,
            rpm_tolerance: 0.10,
            stale_after_ns: 100_000_000,
            window_ns: 250_000_000,
            min_packet_rate_hz: 600.0,
            min_rpm_pairs: 20,
        }
    }
}

/// Why a sensor is out of spec.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum OutOfSpec {
    /// The newest packet is not from a VLP-16.
    #[error("product id {product_id:#04x} is not a VLP-16's (0x22)")]
    ForeignProduct {
        /// The product id seen.
        product_id: u8,
    },
    /// Too few packet pairs yet to measure the rotation rate.
    #[error("rotation rate not measured yet")]
    RotationNotMeasured,
    /// The rotation rate is outside the configured rate +- the tolerance.
    #[error("rotation {rpm:.1} rpm is outside {nominal_rpm:.0} rpm +-{tolerance_pct:.0} %")]
    Rotation {
        /// Measured.
        rpm: f64,
        /// Configured.
        nominal_rpm: f64,
        /// The tolerance, percent.
        tolerance_pct: f64,
    },
    /// Too few packets a second.
    #[error("{rate_hz:.0} packets/s, below the minimum {min_hz:.0} (nominal 753.5, dual 1507)")]
    PacketRate {
        /// Measured over the last full window.
        rate_hz: f64,
        /// The threshold.
        min_hz: f64,
    },
}

/// Whether the sensor's points may be used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SensorVerdict {
    /// Fresh and in spec.
    Ok,
    /// No packet for `age` (`Duration::MAX`: never).
    Stale {
        /// Time since the newest packet arrived.
        age: Duration,
    },
    /// Packets arrive, but from a sensor out of spec.
    OutOfSpec(OutOfSpec),
}

impl SensorVerdict {
    /// Fresh and in spec; anything else counts as a stale scan.
    pub fn is_ok(&self) -> bool {
        matches!(self, Self::Ok)
    }
}

impl std::fmt::Display for SensorVerdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Ok => write!(f, "ok"),
            Self::Stale { age } if *age == Duration::MAX => write!(f, "stale: no packet yet"),
            Self::Stale { age } => {
                write!(f, "stale: no packet for {:.1} ms", age.as_secs_f64() * 1e3)
            }
            Self::OutOfSpec(why) => write!(f, "out of spec: {why}"),
        }
    }
}

/// The last thing that was wrong with a packet.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PacketFault {
    /// It did not decode.
    #[error("{0}")]
    Packet(PacketError),
    /// Its timestamp was not later than the newest seen (beyond the hourly wrap).
    #[error(
        "reordered: timestamp {timestamp_us} us is not after the newest ({newest_us} us on the unwrapped clock)"
    )]
    Reordered {
        /// The packet's timestamp.
        timestamp_us: u32,
        /// The newest seen, unwrapped.
        newest_us: i64,
    },
    /// Its product id is not the VLP-16's.
    #[error("foreign product id {product_id:#04x} (VLP-16: 0x22)")]
    Foreign {
        /// The product id.
        product_id: u8,
    },
}

/// Counters and rates, for logs and reports.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HealthStats {
    /// Packets that decoded.
    pub packets: u64,
    /// Packets of the right length that did not decode.
    pub malformed: u64,
    /// Datagrams of the wrong length (short, or long).
    pub short: u64,
    /// Packets whose timestamp went backwards (apart from the hourly wrap).
    pub reordered: u64,
    /// Packets with a product id other than 0x22.
    pub foreign: u64,
    /// Times the timestamp wrapped past the top of the hour.
    pub hour_wraps: u64,
    /// Revolutions completed (first-block azimuth passing 0).
    pub revolutions: u64,
    /// Packets in the last completed revolution.
    pub last_revolution_packets: u32,
    /// Rotation rate of the last completed revolution (its duration on the sensor clock).
    pub last_revolution_rpm: Option<f64>,
    /// Packets a second over the last full window.
    pub packet_rate_hz: Option<f64>,
    /// Rotation rate over the last full window (or the current one before the first is full).
    pub rpm: Option<f64>,
    /// The newest packet's product id.
    pub product_id: Option<u8>,
    /// The newest packet's return mode.
    pub return_mode: Option<ReturnMode>,
    /// The last fault, named.
    pub last_fault: Option<PacketFault>,
}

#[derive(Debug, Clone, Copy, Default)]
struct Window {
    start_ns: u64,
    packets: u64,
    sum_azimuth_cdeg: f64,
    sum_dt_us: f64,
    pairs: u32,
}

impl Window {
    fn rpm(&self) -> Option<f64> {
        (self.sum_dt_us > 0.0)
            .then(|| self.sum_azimuth_cdeg / f64::from(AZIMUTH_UNITS) / (self.sum_dt_us / 60e6))
    }
}

/// The sensor's health, fed with every datagram (decoded or not) and its host arrival time.
#[derive(Debug, Clone)]
pub struct Health {
    config: HealthConfig,
    clock: HourClock,
    stats: HealthStats,
    newest_arrival_ns: Option<u64>,
    /// First-block azimuth and unwrapped time of the newest forward packet.
    previous: Option<(u16, i64)>,
    window: Window,
    full: Option<(Window, u64)>,
    revolution_start_us: Option<f64>,
    revolution_packets: u32,
}

impl Health {
    /// Health with these thresholds.
    pub fn new(config: HealthConfig) -> Self {
        Self {
            config,
            clock: HourClock::new(),
            stats: HealthStats::default(),
            newest_arrival_ns: None,
            previous: None,
            window: Window::default(),
            full: None,
            revolution_start_us: None,
            revolution_packets: 0,
        }
    }

    /// The thresholds.
    pub fn config(&self) -> &HealthConfig {
        &self.config
    }

    /// The hour clock of the packets seen.
    pub fn clock(&self) -> &HourClock {
        &self.clock
    }

    /// Counters and rates.
    pub fn stats(&self) -> HealthStats {
        self.stats
    }

    fn roll_window(&mut self, arrival_ns: u64) {
        if self.newest_arrival_ns.is_none() {
            self.window.start_ns = arrival_ns;
        } else if arrival_ns.saturating_sub(self.window.start_ns) >= self.config.window_ns {
            let span = arrival_ns - self.window.start_ns;
            self.full = Some((self.window, span));
            self.stats.packet_rate_hz = Some(self.window.packets as f64 * 1e9 / span as f64);
            self.window = Window {
                start_ns: arrival_ns,
                ..Window::default()
            };
        }
    }

    /// A packet that decoded, arrived at `arrival_ns` on the host clock.
    pub fn on_packet(&mut self, packet: &DataPacket, arrival_ns: u64) {
        self.roll_window(arrival_ns);
        self.newest_arrival_ns = Some(
            self.newest_arrival_ns
                .map_or(arrival_ns, |t| t.max(arrival_ns)),
        );
        self.stats.packets += 1;
        self.window.packets += 1;
        self.stats.product_id = Some(packet.product_id);
        self.stats.return_mode = Some(packet.return_mode);
        if packet.product_id != PRODUCT_ID_VLP16 {
            self.stats.foreign += 1;
            self.stats.last_fault = Some(PacketFault::Foreign {
                product_id: packet.product_id,
            });
        }
        let newest_before = self.clock.newest_us();
        let tick = self.clock.tick(packet.timestamp_us, arrival_ns);
        match tick.step {
            ClockStep::Backwards => {
                self.stats.reordered += 1;
                self.stats.last_fault = Some(PacketFault::Reordered {
                    timestamp_us: packet.timestamp_us,
                    newest_us: newest_before.unwrap_or(tick.t_us),
                });
                return;
            }
            ClockStep::Wrapped => self.stats.hour_wraps += 1,
            ClockStep::First | ClockStep::Forward => {}
        }
        let azimuth = packet.blocks[0].azimuth_cdeg;
        self.revolution_packets = self.revolution_packets.saturating_add(1);
        if let Some((previous_azimuth, previous_us)) = self.previous {
            let dt = tick.t_us - previous_us;
            let advance = (i32::from(azimuth) - i32::from(previous_azimuth))
                .rem_euclid(i32::from(AZIMUTH_UNITS));
            if dt > 0 && dt <= 20_000 {
                self.window.sum_azimuth_cdeg += f64::from(advance);
                self.window.sum_dt_us += dt as f64;
                self.window.pairs += 1;
            }
            // A revolution ends where the first block's azimuth passes 0.
            // The crossing's time is interpolated between the two packets' first firings.
            if i32::from(azimuth) < i32::from(previous_azimuth) - i32::from(AZIMUTH_UNITS / 2) {
                let crossing_us = if dt > 0 && advance > 0 {
                    tick.t_us as f64 - f64::from(azimuth) * dt as f64 / f64::from(advance)
                } else {
                    tick.t_us as f64
                };
                if let Some(start) = self.revolution_start_us {
                    let duration_us = crossing_us - start;
                    self.stats.last_revolution_rpm =
                        (duration_us > 0.0).then(|| 60e6 / duration_us);
                    self.stats.last_revolution_packets = self.revolution_packets;
                    self.stats.revolutions += 1;
                }
                self.revolution_start_us = Some(crossing_us);
                self.revolution_packets = 0;
            }
        }
        self.previous = Some((azimuth, tick.t_us));
        self.stats.rpm = match self.full {
            Some((w, _)) if w.pairs >= self.config.min_rpm_pairs => w.rpm(),
            _ if self.window.pairs >= self.config.min_rpm_pairs => self.window.rpm(),
            _ => None,
        };
    }

    /// A datagram that did not decode.
    pub fn on_error(&mut self, error: &PacketError, arrival_ns: u64) {
        let _ = arrival_ns;
        if error.is_wrong_length() {
            self.stats.short += 1;
        } else {
            self.stats.malformed += 1;
        }
        self.stats.last_fault = Some(PacketFault::Packet(*error));
    }

    /// Decodes a datagram and feeds the result in; the packet, if it decoded.
    pub fn on_datagram(&mut self, bytes: &[u8], arrival_ns: u64) -> Option<DataPacket> {
        match DataPacket::decode(bytes) {
            Ok(p) => {
                self.on_packet(&p, arrival_ns);
                Some(p)
            }
            Err(e) => {
                self.on_error(&e, arrival_ns);
                None
            }
        }
    }

    /// Whether the sensor's points may be used at `now_ns` (module docs for the thresholds).
    pub fn verdict(&self, now_ns: u64) -> SensorVerdict {
        let Some(newest) = self.newest_arrival_ns else {
            return SensorVerdict::Stale { age: Duration::MAX };
        };
        let age_ns = now_ns.saturating_sub(newest);
        if age_ns > self.config.stale_after_ns {
            return SensorVerdict::Stale {
                age: Duration::from_nanos(age_ns),
            };
        }
        if let Some(product_id) = self.stats.product_id
            && product_id != PRODUCT_ID_VLP16
        {
            return SensorVerdict::OutOfSpec(OutOfSpec::ForeignProduct { product_id });
        }
        let Some(rpm) = self.stats.rpm else {
            return SensorVerdict::OutOfSpec(OutOfSpec::RotationNotMeasured);
        };
        let nominal = self.config.nominal_rpm;
        let within = (rpm - nominal).abs() <= nominal * self.config.rpm_tolerance;
        if !within {
            return SensorVerdict::OutOfSpec(OutOfSpec::Rotation {
                rpm,
                nominal_rpm: nominal,
                tolerance_pct: self.config.rpm_tolerance * 100.0,
            });
        }
        if let Some(rate_hz) = self.stats.packet_rate_hz
            && rate_hz < self.config.min_packet_rate_hz
        {
            return SensorVerdict::OutOfSpec(OutOfSpec::PacketRate {
                rate_hz,
                min_hz: self.config.min_packet_rate_hz,
            });
        }
        SensorVerdict::Ok
    }

    /// The nominal packet rate in a return mode (753.5 a second single, 1507 dual).
    pub fn nominal_packet_rate_hz(mode: ReturnMode) -> f64 {
        PACKETS_PER_S * mode.blocks_per_cycle() as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hour_wraps_forward_and_a_late_packet_from_before_it_is_reordered() {
        let mut c = HourClock::new();
        assert_eq!(c.tick(3_599_998_000, 0).step, ClockStep::First);
        let t = c.tick(3_599_999_327, 1_327_000);
        assert_eq!((t.t_us, t.step), (3_599_999_327, ClockStep::Forward));
        let t = c.tick(654, 2_654_000);
        assert_eq!((t.t_us, t.step), (3_600_000_654, ClockStep::Wrapped));
        let t = c.tick(3_599_999_900, 2_700_000);
        assert_eq!((t.t_us, t.step), (3_599_999_900, ClockStep::Backwards));
        let t = c.tick(1_981, 3_981_000);
        assert_eq!((t.t_us, t.step), (3_600_001_981, ClockStep::Forward));
        // The host offset is the smallest delay seen: 3.6e9 us earlier than arrival.
        assert_eq!(c.host_offset_ns(), Some(-3_599_998_000_000));
        assert_eq!(c.host_ns(3_600_001_981), Some(3_981_000));
    }
}
