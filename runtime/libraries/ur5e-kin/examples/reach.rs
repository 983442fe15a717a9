//! Prints the arm's horizontal reach (from the arm base axis) for the default placement
//! config, at several object heights, straight down and within the tool-down tolerance.
//!
//! `cargo run --release -p ur5e-kin --example reach`

use core::f64::consts::FRAC_PI_2;
use planar::Pose2;

use nalgebra::Point3;
use ur5e_kin::{PlaceConfig, plan_place};

/// Farthest reachable goal straight ahead of the arm base axis, scanned at 1 mm [m].
fn reach_m(cfg: &PlaceConfig, z_m: f64) -> Option<f64> {
    let base = Pose2 {
        x_m: 0.0,
        y_m: 0.0,
        yaw_rad: FRAC_PI_2,
    };
    let axis_y = cfg.mount.forward_m;
    (0..1500)
        .rev()
        .map(|mm| axis_y + mm as f64 * 0.001)
        .find(|y| plan_place(cfg, base, Point3::new(0.0, *y, z_m), &[]).is_ok())
        .map(|y| y - axis_y)
}

fn main() {
    let tilted = PlaceConfig::default();
    let straight = PlaceConfig {
        down_tolerance_rad: 0.0,
        ..PlaceConfig::default()
    };
    println!(
        "mount: {:.2} m forward, {:.2} m high; TCP {:.2} m; tolerance {:.1} deg",
        tilted.mount.forward_m,
        tilted.mount.height_m,
        tilted.tcp_offset_m,
        tilted.down_tolerance_rad.to_degrees()
    );
    println!("object z [m] | reach straight down [m] | reach within tolerance [m]");
    for z in [1.1, 1.2, 1.3, 1.4, 1.5] {
        let fmt = |r: Option<f64>| r.map_or("-".to_string(), |r| format!("{r:.3}"));
        println!(
            "{z:.1} | {} | {}",
            fmt(reach_m(&straight, z)),
            fmt(reach_m(&tilted, z))
        );
    }
}
