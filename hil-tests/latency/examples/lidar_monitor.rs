//! The range-sensor path's timing, side by side in one run (docs/lidar.md, "Latency"):
//!
//! * a revolution of simulated VLP-16 packets (the example scene, the base standing between
//!   chairs) sent over loopback UDP to the executive's `Vlp16Sensor`: from the revolution's last
//!   packet sent to the obstacles ready for the monitor (drain, decode, health, assemble,
//!   deskew, filter, project);
//! * the collision monitor's check of one command against those obstacles (what the base cycle
//!   runs every 20 ms).
//!
//! `cargo run --release -p latency --example lidar_monitor -- [REVOLUTIONS]` (default 200).

use std::net::UdpSocket;
use std::time::{Duration, Instant};

use grop_onboard::executive::range::{RangeSensor, Vlp16Sensor};
use latency::stats::Summary;
use motion_control::Twist;
use motion_control::collision::{CollisionMonitor, MonitorConfig, MonitorMode, Obstacles};
use planar::Pose2;
use world::{LidarSpec, RayScene, RobotConfig, Scene};

fn main() -> anyhow::Result<()> {
    let revolutions: usize = std::env::args()
        .nth(1)
        .map(|a| a.parse())
        .transpose()?
        .unwrap_or(200);
    let scene = Scene::from_toml_str(
        include_str!("../../../runtime/world/data/example-scene.toml"),
        "example-scene.toml",
    )?;
    let robot = RobotConfig::default();
    let spec = LidarSpec::default();
    let rays = RayScene::from_scene(&scene);
    // Between the chairs at the near side of the banquet table, facing it.
    let pose = Pose2 {
        x_m: 1.0,
        y_m: 4.9,
        yaw_rad: std::f64::consts::FRAC_PI_2,
    };
    let mut sensor = Vlp16Sensor::bind("127.0.0.1:0", &spec, robot.footprint.body_height_m)?;
    let to = sensor
        .local_addr()
        .ok_or_else(|| anyhow::anyhow!("the sensor has no address"))?;
    let tx = UdpSocket::bind("127.0.0.1:0")?;
    let calib = vlp16::calib::Calibration {
        min_range_m: spec.min_range_m,
        max_range_m: spec.max_range_m,
        ..vlp16::calib::Calibration::VLP16
    };
    let mut emitter =
        vlp16::sim::Emitter::new(spec.rpm, vlp16::packet::ReturnMode::Strongest, calib, 0)?;
    let (s, c) = pose.yaw_rad.sin_cos();
    let mut cast = |f: vlp16::sim::Firing| {
        let d = f.direction();
        let dir = [c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]];
        rays.cast(
            [pose.x_m, pose.y_m, spec.mount.z_m + f.origin()[2]],
            dir,
            100.0,
        )
        .map(|(r, _)| (r, 40))
    };
    let fp = robot.footprint;
    let mut monitor = CollisionMonitor::new(MonitorConfig::for_footprint(
        fp.length_m as f32,
        fp.width_m as f32,
    ));
    let mut obstacles = Obstacles::new();
    let (mut to_ready, mut check) = (Vec::new(), Vec::new());
    let mut points = 0usize;
    let period_us = 60e6 / spec.rpm;
    let start = Instant::now();
    for k in 0..revolutions + 2 {
        // Send one revolution, then poll as the base cycle would.
        let until = ((k + 1) as f64 * period_us) as u64;
        let mut last_sent = Instant::now();
        emitter.emit_until(until, &mut cast, &mut |bytes, _| {
            let _ = tx.send_to(bytes, to);
            last_sent = Instant::now();
        });
        let now = start.elapsed() + Duration::from_micros(until);
        let fresh = sensor.poll(now, 0.0, 0.0, &mut obstacles);
        let ready = last_sent.elapsed();
        if !fresh || k < 2 {
            continue;
        }
        to_ready.push(ready.as_nanos() as u64);
        points = obstacles.len();
        monitor.set_scan(&obstacles);
        let now_us = u64::try_from(now.as_micros()).unwrap_or(u64::MAX);
        let t0 = Instant::now();
        let v = monitor.check(Twist::new(0.3, 0.2), MonitorMode::Normal, now_us);
        check.push(t0.elapsed().as_nanos() as u64);
        std::hint::black_box(v);
    }
    let (r, c1) = (Summary::of(&mut to_ready), Summary::of(&mut check));
    println!(
        "| measurement ({revolutions} revolutions, {points} bearings kept) | p50 | p99 | max |"
    );
    println!("|---|---|---|---|");
    for (name, s) in [
        (
            "revolution's last packet sent -> obstacles ready (UDP, decode, health, assemble, deskew, project)",
            r,
        ),
        (
            "monitor check of one command (the kept bearings, 20 projection steps)",
            c1,
        ),
    ] {
        println!(
            "| {name} | {:.1} us | {:.1} us | {:.1} us |",
            s.p50_us(),
            s.p99_us(),
            s.max_us()
        );
    }
    Ok(())
}
