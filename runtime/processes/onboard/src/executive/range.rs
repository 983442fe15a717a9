//! The range sensor as the shell reads it, and what the collision monitor checks: the scan's
//! obstacle points plus the prior map's overhangs the sensor cannot see.
//!
//! The shell owns a [`RangeSensor`] (the VLP-16 over UDP on the robot and in HIL) and a
//! [`CollisionMonitor`]. Every base cycle it polls the sensor; a completed revolution replaces
//! the monitor's obstacles, then the map's overhangs are added from the localisation estimate.
//! Between revolutions the obstacles are moved by the odometry (deskewed to the base's frame
//! now). The core's velocity goes through [`CollisionMonitor::check`] last, just before the base
//! driver.

use std::time::Duration;

use motion_control::collision::Obstacles;
use world::Scene;

use planar::Pose2;

/// A range sensor as the shell polls it (never blocks).
pub trait RangeSensor: Send {
    /// Reads whatever arrived. When a revolution completed since the last call, fills `out`
    /// with its points between the floor filter and the body's height, projected on the floor,
    /// in the base frame as of the revolution's end (deskewed under the base's velocity
    /// `speed_mps`, `yaw_rate_radps`), stamps it `now`, and returns true. A sensor out of spec
    /// (silent, rotating at the wrong rate, a foreign device) returns false: the monitor's scan
    /// goes stale and the base stops.
    fn poll(
        &mut self,
        now: Duration,
        speed_mps: f32,
        yaw_rate_radps: f32,
        out: &mut Obstacles,
    ) -> bool;

    /// One line on the sensor's health for logs and reports.
    fn status(&self, now: Duration) -> String;
}

/// Returns lower than this above the floor are the floor (m).
pub const FLOOR_FILTER_M: f32 = 0.05;

/// Table tops and other overhangs of the prior map, as segments in the world frame: the edges
/// the sensor's rings may pass under. Sampled into obstacle points every scan.
#[derive(Debug, Clone, Default)]
pub struct MapOverhangs {
    edges: Vec<[f64; 4]>,
}

/// Spacing of the overhang points along an edge (m).
const OVERHANG_STEP_M: f64 = 0.05;
/// Overhang points farther than this from the base are left out (m).
const OVERHANG_RANGE_M: f64 = 3.0;

impl MapOverhangs {
    /// The banquet table's and the loading table's top edges of `scene` (both are tops on legs:
    /// the sensor at its mounting height sees their legs up close and their tops only from
    /// afar).
    pub fn of_scene(scene: &Scene) -> Self {
        let mut edges = Vec::new();
        let mut rect = |x0: f64, x1: f64, y0: f64, y1: f64| {
            edges.push([x0, y0, x1, y0]);
            edges.push([x1, y0, x1, y1]);
            edges.push([x1, y1, x0, y1]);
            edges.push([x0, y1, x0, y0]);
        };
        let bt = &scene.banquet_table;
        rect(bt.x_min_m(), bt.x_max_m(), bt.y_min_m(), bt.y_max_m());
        let (x0, x1, y0, y1) = scene.loading_table.footprint().bounds();
        rect(x0, x1, y0, y1);
        Self { edges }
    }

    /// Adds the overhang points near `estimate` to `out`, in the base frame of the estimate.
    pub fn add_to(&self, estimate: Pose2, own: [f32; 2], out: &mut Obstacles) {
        let (s, c) = estimate.yaw_rad.sin_cos();
        for e in &self.edges {
            let (dx, dy) = (e[2] - e[0], e[3] - e[1]);
            let length = dx.hypot(dy);
            let n = (length / OVERHANG_STEP_M).ceil().max(1.0) as usize;
            for k in 0..=n {
                let t = k as f64 / n as f64;
                let (wx, wy) = (e[0] + t * dx - estimate.x_m, e[1] + t * dy - estimate.y_m);
                if wx.hypot(wy) > OVERHANG_RANGE_M {
                    continue;
                }
                let bx = c * wx + s * wy;
                let by = -s * wx + c * wy;
                out.add(bx as f32, by as f32, own);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overhangs_are_the_table_edges_near_the_base_in_its_frame() {
        let scene = Scene::from_toml_str(
            include_str!("../../../../libraries/world/data/example-scene.toml"),
            "example-scene.toml",
        )
        .expect("example scene");
        let overhangs = MapOverhangs::of_scene(&scene);
        let mut out = Obstacles::new();
        out.clear(0);
        // 0.5 m in front of the banquet table's near edge, facing it.
        let near_y = scene.banquet_table.y_min_m();
        let pose = Pose2::new(0.0, near_y - 0.5, std::f64::consts::FRAC_PI_2);
        overhangs.add_to(pose, [0.3, 0.275], &mut out);
        assert!(!out.is_empty());
        // The nearest point is straight ahead, 0.5 m.
        let nearest = out
            .iter()
            .min_by(|a, b| a[0].hypot(a[1]).total_cmp(&b[0].hypot(b[1])))
            .expect("points");
        assert!(
            (nearest[0] - 0.5).abs() < 1e-3 && nearest[1].abs() < 0.03,
            "{nearest:?}"
        );
        // Far from every table: nothing.
        let mut far = Obstacles::new();
        far.clear(0);
        overhangs.add_to(Pose2::new(8.0, 2.5, 0.0), [0.3, 0.275], &mut far);
        assert!(far.is_empty());
    }
}

/// The Velodyne VLP-16 over UDP (the robot's sensor; in HIL the world's simulated one on
/// loopback): decodes the packets, checks the sensor's health, assembles revolutions, deskews
/// them under the base's velocity and keeps the returns between [`FLOOR_FILTER_M`] and the
/// body's height.
pub struct Vlp16Sensor {
    source: vlp16::udp::UdpSource,
    health: vlp16::health::Health,
    assembler: vlp16::scan::ScanAssembler,
    /// Returns above this are over the robot (m).
    body_height_m: f32,
    /// A revolution completed since the last poll.
    fresh: bool,
    /// The last revolution's returns the monitor keeps (preallocated).
    kept: Vec<vlp16::scan::Point>,
    io_errors: u64,
}

/// Why the VLP-16 could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum SensorError {
    /// The UDP port could not be bound.
    #[error("lidar: cannot listen on {addr}: {source}")]
    Bind {
        /// The address.
        addr: String,
        /// The socket error.
        source: std::io::Error,
    },
    /// The robot file's sensor does not make a valid configuration.
    #[error("lidar: the robot file's [lidar] section: {0}")]
    Config(String),
}

impl Vlp16Sensor {
    /// Listens on `addr` (`host:port`) for the sensor the robot file describes (`spec`, at the
    /// base's body height `body_height_m`).
    pub fn bind(
        addr: &str,
        spec: &world::LidarSpec,
        body_height_m: f64,
    ) -> Result<Self, SensorError> {
        let source = vlp16::udp::UdpSource::bind(addr).map_err(|source| SensorError::Bind {
            addr: addr.to_owned(),
            source,
        })?;
        let calib = vlp16::calib::Calibration {
            min_range_m: spec.min_range_m,
            max_range_m: spec.max_range_m,
            ..vlp16::calib::Calibration::VLP16
        };
        let mount = vlp16::Mount {
            x_m: spec.mount.x_m,
            y_m: spec.mount.y_m,
            z_m: spec.mount.z_m,
            yaw_rad: spec.mount.yaw_rad,
        };
        let assembler = vlp16::scan::ScanAssembler::new(calib, mount, &[], 32_768)
            .map_err(|e| SensorError::Config(e.to_string()))?;
        let health = vlp16::health::Health::new(vlp16::health::HealthConfig {
            nominal_rpm: spec.rpm,
            ..vlp16::health::HealthConfig::default()
        });
        Ok(Self {
            source,
            health,
            assembler,
            body_height_m: body_height_m as f32,
            fresh: false,
            kept: Vec::with_capacity(32_768),
            io_errors: 0,
        })
    }

    /// The address it listens on.
    pub fn local_addr(&self) -> Option<std::net::SocketAddr> {
        self.source.local_addr().ok()
    }
}

impl Vlp16Sensor {
    /// Takes packets only from the sensor's address (`lidar_sensor` in the deployment); other
    /// senders' are dropped and counted (docs/security.md).
    pub fn only_from(&mut self, sensor: std::net::IpAddr) {
        self.source.only_from(sensor);
    }
}

impl RangeSensor for Vlp16Sensor {
    fn poll(
        &mut self,
        now: Duration,
        speed_mps: f32,
        yaw_rate_radps: f32,
        out: &mut Obstacles,
    ) -> bool {
        let now_ns = u64::try_from(now.as_nanos()).unwrap_or(u64::MAX);
        let (health, assembler, fresh) = (&mut self.health, &mut self.assembler, &mut self.fresh);
        let drained = self.source.drain(|packet| match packet {
            Ok(p) => {
                health.on_packet(&p, now_ns);
                if assembler.push(&p, now_ns).is_some() {
                    *fresh = true;
                }
            }
            Err(e) => health.on_error(&e, now_ns),
        });
        if drained.is_err() {
            self.io_errors += 1;
        }
        if !self.health.verdict(now_ns).is_ok() || !std::mem::take(&mut self.fresh) {
            return false;
        }
        let Some(done) = self.assembler.last_done() else {
            return false;
        };
        let now_us = u64::try_from(now.as_micros()).unwrap_or(u64::MAX);
        out.clear(now_us);
        // The returns between the floor and the body's height, deskewed into the base frame at
        // the revolution's end (the base having moved on at its velocity since each firing).
        self.kept.clear();
        self.kept.extend(
            self.assembler
                .points()
                .iter()
                .filter(|p| p.z >= FLOOR_FILTER_M && p.z <= self.body_height_m),
        );
        vlp16::scan::deskew(
            &mut self.kept,
            f64::from(speed_mps),
            f64::from(yaw_rate_radps),
            done.end_us,
        );
        for p in &self.kept {
            out.add(p.x, p.y, [0.0, 0.0]);
        }
        true
    }

    fn status(&self, now: Duration) -> String {
        let now_ns = u64::try_from(now.as_nanos()).unwrap_or(u64::MAX);
        let s = self.health.stats();
        format!(
            "vlp16 {:?}: {} packets, rpm {:?}, {} socket errors, {} datagrams from other senders dropped",
            self.health.verdict(now_ns),
            s.packets,
            s.rpm,
            self.io_errors,
            self.source.foreign_sender
        )
    }
}
