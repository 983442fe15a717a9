use nalgebra::Point3;
use ur5e_kin::*;
fn main() {
    for (tol, h, tcp) in [(0.0, 1.05, 0.2), (10.0, 1.05, 0.2), (15.0, 1.05, 0.2), (15.0, 1.0, 0.2), (15.0, 1.1, 0.2), (15.0, 1.05, 0.23), (10.0, 1.0, 0.23)] {
        let mut cfg = PlaceConfig::default();
        cfg.down_tolerance_rad = f64::to_radians(tol);
        cfg.mount.height_m = h;
        cfg.tcp_offset_m = tcp;
        let base = BasePose { x_m: 0.0, y_m: 0.0, yaw_rad: core::f64::consts::FRAC_PI_2 };
        let arm_y = cfg.mount.forward_m;
        let z = 1.3;
        let last = (0..600).map(|i| i as f64 * 0.0025).filter(|y| plan_place(&cfg, base, Point3::new(0.0, *y, z), &[]).is_ok()).last();
        println!("tol {tol} h {h} tcp {tcp}: reach {:?}", last.map(|l| l - arm_y));
    }
}
