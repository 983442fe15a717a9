//! Writes two revolutions of the simulated VLP-16 as a pcap file, with our decoding of them, for
//! the third-party check (`.ci/vlp16-decoder-check.sh`, docs/lidar.md):
//!
//! ```sh
//! cargo run -p vlp16 --example sim_pcap -- OUT_DIR
//! ```
//!
//! `OUT_DIR/sim.pcap`: the data packets as captured on the wire (Ethernet, IPv4, UDP to port
//! 2368). `OUT_DIR/points.csv`: every return of every packet (distance 0 left out), decoded by
//! this crate in the sensor frame (x forward, y left, z up): packet, block, sequence, laser,
//! x, y, z in metres and the azimuth in degrees (clockwise, the sensor's convention).
//!
//! The scene: the sensor 0.45 m above a floor, inside a wall that is a 3 m circle around it,
//! with a 30-degree doorway without returns; the sensor turns at 600 rpm, starting at azimuth
//! 123.4 degrees, its clock 2 ms before the top of the hour; the calibration is
//! `Calibration::VLP16` (the vertical offsets `velodyne-decoder` builds in for the VLP-16 too).

use std::fmt::Write as _;
use std::io::BufWriter;
use std::path::PathBuf;

use vlp16::calib::Calibration;
use vlp16::packet::{DataPacket, ReturnMode};
use vlp16::pcap::PcapWriter;
use vlp16::scan::packet_points;
use vlp16::sim::{Emitter, Firing};

const SENSOR_HEIGHT_M: f64 = 0.45;
const WALL_RADIUS_M: f64 = 3.0;

fn cast(f: Firing) -> Option<(f64, u8)> {
    let d = f.direction();
    // The doorway: sensor-frame directions between 40 and 70 degrees see nothing.
    let direction_deg = f.azimuth_rad.to_degrees();
    if (40.0..70.0).contains(&direction_deg) {
        return None;
    }
    let o = f.origin();
    // Where the ray from its origin meets the wall (a vertical cylinder about the sensor).
    let (a, b) = (d[0] * d[0] + d[1] * d[1], o[0] * d[0] + o[1] * d[1]);
    let c = o[0] * o[0] + o[1] * o[1] - WALL_RADIUS_M * WALL_RADIUS_M;
    let mut range = (-b + (b * b - a * c).sqrt()) / a;
    let mut reflectivity = 60;
    if d[2] < 0.0 {
        let to_floor = (SENSOR_HEIGHT_M + o[2]) / -d[2];
        if to_floor < range {
            range = to_floor;
            reflectivity = 15;
        }
    }
    Some((range, reflectivity + f.laser))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(std::env::args().nth(1).ok_or("usage: sim_pcap OUT_DIR")?);
    std::fs::create_dir_all(&dir)?;
    let calib = Calibration::VLP16;
    // 2026-12-05 00:59:59.998 UTC, in microseconds since the epoch: the packets' hour clock
    // wraps 2 ms in.
    let start_us: u64 = 1_796_432_399_998_000;
    let mut emitter =
        Emitter::new(600.0, ReturnMode::Strongest, calib, start_us)?.with_start_azimuth_deg(123.4);
    let pcap_path = dir.join("sim.pcap");
    let mut pcap = PcapWriter::new(BufWriter::new(std::fs::File::create(&pcap_path)?))?;
    let trig = calib.trig();
    let mut csv = String::from("packet,block,seq,laser,x_m,y_m,z_m,azimuth_deg\n");
    let mut packets = 0usize;
    let mut points = 0usize;
    let mut failure: Option<std::io::Error> = None;
    emitter.emit_until(start_us + 200_000, &mut cast, &mut |bytes, t_us| {
        if let Err(e) = pcap.write_packet(bytes, t_us) {
            failure.get_or_insert(e);
        }
        match DataPacket::decode(bytes) {
            Ok(p) => packet_points(&p, &trig, |block, seq, laser, xyz, azimuth_cdeg| {
                points += 1;
                let _ = writeln!(
                    csv,
                    "{packets},{block},{seq},{laser},{:.6},{:.6},{:.6},{:.5}",
                    xyz[0],
                    xyz[1],
                    xyz[2],
                    azimuth_cdeg / 100.0
                );
            }),
            Err(e) => {
                failure.get_or_insert(std::io::Error::other(format!("packet {packets}: {e}")));
            }
        }
        packets += 1;
    });
    if let Some(e) = failure {
        return Err(e.into());
    }
    pcap.finish()?;
    std::fs::write(dir.join("points.csv"), csv)?;
    println!(
        "sim_pcap: {packets} packets, {points} points -> {} and points.csv",
        pcap_path.display()
    );
    Ok(())
}
