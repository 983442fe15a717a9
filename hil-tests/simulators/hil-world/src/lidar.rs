//! The simulated VLP-16 on the moving base: every firing of the real sensor's schedule is a ray
//! cast against the true furniture ([`world::RayScene`]) from where the base is at that step,
//! with range noise and dropouts, and the packets go to the executive over UDP on loopback. In
//! lock-step, the world sends every packet whose last firing lies at or before the step's time
//! before it advances the clock, so a replayed mission gets the same packets.

use std::net::{SocketAddr, UdpSocket};

use planar::Pose2;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use world::{LidarSpec, RayScene, Scene};

/// Reflectivity reported for every return (the world has no materials).
const REFLECTIVITY: u8 = 40;

/// The world's sensor.
pub struct SimLidar {
    spec: LidarSpec,
    rays: RayScene,
    emitter: vlp16::sim::Emitter,
    socket: UdpSocket,
    to: SocketAddr,
    rng: ChaCha8Rng,
    noise: Normal<f64>,
    /// Packets sent, and sends that failed (the executive not yet listening).
    pub sent: u64,
    /// Sends that failed.
    pub send_errors: u64,
}

/// Why the sensor could not start.
#[derive(Debug, thiserror::Error)]
pub enum SimLidarError {
    /// The socket.
    #[error("simulated lidar socket: {0}")]
    Socket(#[from] std::io::Error),
    /// The robot file's sensor.
    #[error("simulated lidar: {0}")]
    Config(String),
}

impl SimLidar {
    /// A sensor as the robot file's `[lidar]` says, over `scene`, sending to a loopback port it
    /// picks ([`Self::port`]), seeded by `seed`.
    pub fn new(scene: &Scene, spec: LidarSpec, seed: u64) -> Result<Self, SimLidarError> {
        let calib = vlp16::calib::Calibration {
            min_range_m: spec.min_range_m,
            max_range_m: spec.max_range_m,
            ..vlp16::calib::Calibration::VLP16
        };
        let emitter =
            vlp16::sim::Emitter::new(spec.rpm, vlp16::packet::ReturnMode::Strongest, calib, 0)
                .map_err(|e| SimLidarError::Config(e.to_string()))?;
        // The executive listens on a port the world names: reserve one the OS picks, then let
        // it go for the executive to bind (a port taken in between makes the executive's start
        // fail loudly, never a silent sensor).
        let to = UdpSocket::bind("127.0.0.1:0")?.local_addr()?;
        let socket = UdpSocket::bind("127.0.0.1:0")?;
        let noise = Normal::new(0.0, spec.range_noise_sigma_m.max(0.0))
            .map_err(|e| SimLidarError::Config(e.to_string()))?;
        Ok(Self {
            spec,
            rays: RayScene::from_scene(scene),
            emitter,
            socket,
            to,
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x11DA_2000),
            noise,
            sent: 0,
            send_errors: 0,
        })
    }

    /// The loopback port the packets go to.
    pub fn port(&self) -> u16 {
        self.to.port()
    }

    /// Furniture moved: the rays see the new scene.
    pub fn set_scene(&mut self, scene: &Scene) {
        self.rays = RayScene::from_scene(scene);
    }

    /// Sends every packet due by `now_us` (simulated microseconds), cast from `pose`.
    pub fn step(&mut self, now_us: u64, pose: Pose2) {
        let m = self.spec.mount;
        let (sb, cb) = pose.yaw_rad.sin_cos();
        let origin_xy = [
            pose.x_m + cb * m.x_m - sb * m.y_m,
            pose.y_m + sb * m.x_m + cb * m.y_m,
        ];
        let sensor_yaw = pose.yaw_rad + m.yaw_rad;
        let (ss, cs) = sensor_yaw.sin_cos();
        let (rays, rng, noise, spec) = (&self.rays, &mut self.rng, &self.noise, &self.spec);
        let (socket, to) = (&self.socket, self.to);
        let (mut sent, mut errors) = (0u64, 0u64);
        self.emitter.emit_until(
            now_us,
            &mut |firing| {
                if rng.random::<f64>() < spec.dropout_probability {
                    return None;
                }
                let d = firing.direction();
                let o = firing.origin();
                let world_dir = [cs * d[0] - ss * d[1], ss * d[0] + cs * d[1], d[2]];
                let world_origin = [origin_xy[0], origin_xy[1], m.z_m + o[2]];
                let (range, _) = rays.cast(world_origin, world_dir, spec.max_range_m)?;
                let noisy = range + noise.sample(rng);
                (noisy >= spec.min_range_m).then_some((noisy, REFLECTIVITY))
            },
            &mut |bytes, _t| match socket.send_to(bytes, to) {
                Ok(_) => sent += 1,
                Err(_) => errors += 1,
            },
        );
        self.sent += sent;
        self.send_errors += errors;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sensor_sends_a_revolution_that_sees_a_chair_in_front() {
        let mut scene = Scene::empty_paper_room();
        scene.chairs = vec![world::Chair::new(2.0, 1.0, 0.0)];
        let mut lidar = SimLidar::new(&scene, LidarSpec::default(), 1).expect("lidar");
        let rx = UdpSocket::bind(("127.0.0.1", lidar.port())).expect("bind");
        rx.set_nonblocking(true).expect("nonblocking");
        let pose = Pose2 {
            x_m: 1.0,
            y_m: 1.0,
            yaw_rad: 0.0,
        };
        // 50 ms: about 37 packets.
        for t in (0..=50_000).step_by(2_000) {
            lidar.step(t, pose);
        }
        let mut buf = [0u8; 2048];
        let mut chair_hits = 0;
        let mut packets = 0;
        while let Ok(n) = rx.recv(&mut buf) {
            packets += 1;
            let p = vlp16::packet::DataPacket::decode(&buf[..n]).expect("valid packet");
            for block in p.blocks {
                // The chair's near face is 0.775 m ahead: azimuth ~0 (clockwise), level lasers.
                let az = f64::from(block.azimuth_cdeg) / 100.0;
                if (5.0..=355.0).contains(&az) {
                    continue;
                }
                for r in block.returns {
                    let d = r.distance_m();
                    if (0.7..0.85).contains(&d) {
                        chair_hits += 1;
                    }
                }
            }
        }
        assert!((35..=40).contains(&packets), "{packets} packets in 50 ms");
        assert_eq!(lidar.sent, packets);
        // 50 ms at 600 rpm is half a turn from azimuth 0: the chair's bearing is in it.
        assert!(chair_hits > 20, "{chair_hits} returns off the chair");
    }
}
