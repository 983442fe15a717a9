//! The driver end to end: hand-built packets to points, the hour wrap, health verdicts, drops,
//! the simulated sensor against a known shape, deskewing, UDP over loopback.

use std::f64::consts::PI;

use proptest::prelude::*;
use vlp16::calib::{Calibration, PACKETS_PER_S};
use vlp16::health::{Health, HealthConfig, OutOfSpec, PacketFault, SensorVerdict};
use vlp16::packet::{
    BLOCKS, Block, DataPacket, PAYLOAD_LEN, PRODUCT_ID_VLP16, RETURNS_PER_BLOCK, Return, ReturnMode,
};
use vlp16::scan::{Point, ScanAssembler, deskew};
use vlp16::sim::Emitter;
use vlp16::udp::UdpSource;
use vlp16::{BlindSector, Mount};

fn packet(azimuths: [u16; BLOCKS], timestamp_us: u32) -> DataPacket {
    let mut blocks = [Block {
        azimuth_cdeg: 0,
        returns: [Return::default(); RETURNS_PER_BLOCK],
    }; BLOCKS];
    for (b, a) in blocks.iter_mut().zip(azimuths) {
        b.azimuth_cdeg = a;
    }
    DataPacket {
        blocks,
        timestamp_us,
        return_mode: ReturnMode::Strongest,
        product_id: PRODUCT_ID_VLP16,
    }
}

fn steady(first: u16, gap: u16) -> [u16; BLOCKS] {
    std::array::from_fn(|k| ((u32::from(first) + u32::from(gap) * k as u32) % 36_000) as u16)
}

/// The expected base-frame point of a return, written out from the manual's formulas.
fn expected(
    mount: Mount,
    calib: &Calibration,
    laser: usize,
    d: f64,
    azimuth_cdeg: f64,
) -> [f64; 3] {
    let w = calib.elevation_deg[laser].to_radians();
    let a = (azimuth_cdeg / 100.0).to_radians();
    let s = [
        d * w.cos() * a.cos(),
        -d * w.cos() * a.sin(),
        d * w.sin() + calib.vertical_offset_mm[laser] / 1000.0,
    ];
    let (sy, cy) = mount.yaw_rad.sin_cos();
    [
        mount.x_m + cy * s[0] - sy * s[1],
        mount.y_m + sy * s[0] + cy * s[1],
        mount.z_m + s[2],
    ]
}

fn assembler(mount: Mount, blind: &[BlindSector]) -> ScanAssembler {
    ScanAssembler::new(Calibration::VLP16, mount, blind, 30_000).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn a_hand_built_packet_decodes_to_known_points() {
    let mount = Mount {
        x_m: 0.2,
        y_m: -0.1,
        z_m: 0.45,
        yaw_rad: 0.3,
    };
    let mut a = assembler(mount, &[]);
    // Block azimuths 9000, 9040, 9079, 9119 ... 9435: gaps of 40 and 39 as a sensor at about
    // 596 rpm reports them; every firing is interpolated at the packet's mean gap, 435 / 11.
    let mut p = packet(
        std::array::from_fn(|k| (9_000 + 40 * k - k / 2) as u16),
        1_000_000,
    );
    let g = 435.0 / 11.0;
    // Block 0: laser 1 first sequence (azimuth 9000 + g * 2.304 / 110.592), laser 0 second
    // sequence (9000 + g * 0.5: the interpolated second sequence), laser 15 second sequence
    // (9000 + g * (55.296 + 34.56) / 110.592).
    p.blocks[0].returns[1] = Return {
        distance_2mm: 1000,
        reflectivity: 40,
    };
    p.blocks[0].returns[16] = Return {
        distance_2mm: 1500,
        reflectivity: 41,
    };
    p.blocks[0].returns[31] = Return {
        distance_2mm: 700,
        reflectivity: 42,
    };
    // The last block (11, azimuth 9435).
    p.blocks[11].returns[16 + 5] = Return {
        distance_2mm: 900,
        reflectivity: 43,
    };
    assert!(a.push(&p, 1_000).is_none());
    // The next packet passes azimuth 0: the revolution (partial: the first) is done.
    let next = packet(steady(35_990, 40), 1_001_327);
    let done = a
        .push(&next, 2_000)
        .unwrap_or_else(|| panic!("no revolution"));
    assert!(!done.complete);
    assert_eq!(done.points, 4);
    assert_eq!(
        done.dropped.no_return,
        (12 * 32 - 4) as u64 + 16,
        "{done:?}"
    );
    let c = Calibration::VLP16;
    let cases: [(usize, f64, f64, i64); 4] = [
        (1, 2.0, 9_000.0 + g * 2.304 / 110.592, 1_000_000 + 2),
        (0, 3.0, 9_000.0 + g * 0.5, 1_000_000 + 55),
        (
            15,
            1.4,
            9_000.0 + g * (55.296 + 34.56) / 110.592,
            1_000_000 + 90,
        ),
        (
            5,
            1.8,
            9_435.0 + g * (55.296 + 5.0 * 2.304) / 110.592,
            1_000_000 + 1_283,
        ),
    ];
    for (point, (laser, d, azimuth, t_us)) in a.points().iter().zip(cases) {
        let e = expected(mount, &c, laser, d, azimuth);
        assert_eq!(usize::from(point.laser), laser);
        assert_eq!(point.t_us, t_us, "{point:?}");
        for (got, want) in [point.x, point.y, point.z].iter().zip(e) {
            assert!(
                (f64::from(*got) - want).abs() < 1e-6,
                "laser {laser}: {point:?} vs {e:?}"
            );
        }
    }
    assert_eq!(a.points()[0].intensity, 40);
}

#[test]
fn the_hour_wrap_keeps_firing_times_monotonic() {
    let mut a = assembler(Mount::IDENTITY, &[]);
    let mut times = Vec::new();
    let mut azimuth = 0u32;
    let mut toh: u64 = 3_599_995_000;
    for k in 0..10 {
        let mut p = packet(steady(azimuth as u16, 40), (toh % 3_600_000_000) as u32);
        for b in p.blocks.iter_mut() {
            b.returns[0] = Return {
                distance_2mm: 1000,
                reflectivity: 1,
            };
        }
        if let Some(_done) = a.push(&p, k * 1_327_000) {
            times.extend(a.points().iter().map(|p| p.t_us));
        }
        azimuth = (azimuth + 480) % 36_000;
        toh += 1327;
        // Force a revolution cut on the last packet.
        if k == 8 {
            azimuth = 35_900;
        }
    }
    let mut p = packet(steady(100, 40), (toh % 3_600_000_000) as u32);
    p.blocks[0].returns[0] = Return {
        distance_2mm: 1000,
        reflectivity: 1,
    };
    if a.push(&p, 20_000_000).is_some() {
        times.extend(a.points().iter().map(|p| p.t_us));
    }
    assert!(times.len() >= 100, "{}", times.len());
    assert!(times.windows(2).all(|w| w[0] < w[1]), "{times:?}");
    assert!(times.iter().any(|&t| t > 3_600_000_000) && times[0] < 3_600_000_000);
}

fn feed(health: &mut Health, emitter: &mut Emitter, until_us: u64) {
    emitter.emit_until(until_us, &mut |_| Some((4.0, 10)), &mut |bytes, t_us| {
        health.on_datagram(bytes, t_us * 1000);
    });
}

#[test]
fn health_verdicts() {
    let cfg = HealthConfig::default();
    // Nothing yet: stale.
    let mut h = Health::new(cfg);
    assert!(matches!(h.verdict(0), SensorVerdict::Stale { .. }));
    // A nominal sensor: ok, at about 753.5 packets a second.
    let mut e = Emitter::new(600.0, ReturnMode::Strongest, Calibration::VLP16, 5_000_000)
        .unwrap_or_else(|err| panic!("{err}"));
    feed(&mut h, &mut e, 6_000_000);
    assert_eq!(
        h.verdict(6_000_000_000),
        SensorVerdict::Ok,
        "{:?}",
        h.stats()
    );
    let stats = h.stats();
    assert!(
        (stats.packet_rate_hz.unwrap_or(0.0) - PACKETS_PER_S).abs() < 10.0,
        "{stats:?}"
    );
    assert!((stats.rpm.unwrap_or(0.0) - 600.0).abs() < 1.0, "{stats:?}");
    assert!(
        (stats.last_revolution_rpm.unwrap_or(0.0) - 600.0).abs() < 2.0,
        "{stats:?}"
    );
    assert!(
        (74..=76).contains(&stats.last_revolution_packets),
        "{stats:?}"
    );
    // Silence: 100 ms is still fresh, more is stale.
    let last = 6_000_000_000;
    assert_eq!(h.verdict(last + 90_000_000), SensorVerdict::Ok);
    assert!(
        matches!(h.verdict(last + 150_000_000), SensorVerdict::Stale { age } if age.as_millis() >= 149)
    );
    // Slow rotation: 300 rpm against a configured 600 is out of spec.
    let mut slow = Health::new(cfg);
    let mut e = Emitter::new(300.0, ReturnMode::Strongest, Calibration::VLP16, 0)
        .unwrap_or_else(|err| panic!("{err}"));
    feed(&mut slow, &mut e, 500_000);
    let v = slow.verdict(500_000_000);
    assert!(
        matches!(v, SensorVerdict::OutOfSpec(OutOfSpec::Rotation { rpm, .. }) if (rpm - 300.0).abs() < 1.0),
        "{v:?}"
    );
    assert!(!v.is_ok());
    // 655 rpm is within 600 +- 10 %, 665 is not.
    for (rpm, ok) in [(655.0, true), (665.0, false)] {
        let mut h = Health::new(cfg);
        let mut e = Emitter::new(rpm, ReturnMode::Strongest, Calibration::VLP16, 0)
            .unwrap_or_else(|err| panic!("{err}"));
        feed(&mut h, &mut e, 400_000);
        assert_eq!(
            h.verdict(400_000_000).is_ok(),
            ok,
            "{rpm}: {:?}",
            h.verdict(400_000_000)
        );
    }
    // A foreign product id (a VLP-32C's 0x28) is decoded, counted and out of spec.
    let mut h = Health::new(cfg);
    let mut e = Emitter::new(600.0, ReturnMode::Strongest, Calibration::VLP16, 0)
        .unwrap_or_else(|err| panic!("{err}"))
        .with_product_id(0x28);
    feed(&mut h, &mut e, 400_000);
    assert_eq!(
        h.verdict(400_000_000),
        SensorVerdict::OutOfSpec(OutOfSpec::ForeignProduct { product_id: 0x28 })
    );
    assert!(h.stats().foreign > 250);
    assert!(h.verdict(400_000_000).to_string().contains("0x28"));
}

#[test]
fn packet_loss_is_out_of_spec() {
    let mut h = Health::new(HealthConfig::default());
    let mut e = Emitter::new(600.0, ReturnMode::Strongest, Calibration::VLP16, 0)
        .unwrap_or_else(|err| panic!("{err}"));
    let mut k = 0u64;
    e.emit_until(1_000_000, &mut |_| None, &mut |bytes, t_us| {
        k += 1;
        // Every third packet lost: ~502 a second.
        if k % 3 != 0 {
            h.on_datagram(bytes, t_us * 1000);
        }
    });
    let v = h.verdict(1_000_000_000);
    assert!(
        matches!(v, SensorVerdict::OutOfSpec(OutOfSpec::PacketRate { .. })),
        "{v:?}"
    );
}

#[test]
fn reordered_malformed_and_short_packets_are_counted_and_named() {
    let mut h = Health::new(HealthConfig::default());
    let a = packet(steady(0, 40), 10_000);
    let b = packet(steady(480, 40), 11_327);
    h.on_packet(&a, 1_000);
    h.on_packet(&b, 2_000);
    h.on_packet(&a, 3_000);
    assert_eq!(h.stats().reordered, 1);
    assert!(matches!(
        h.stats().last_fault,
        Some(PacketFault::Reordered {
            timestamp_us: 10_000,
            ..
        })
    ));
    let mut bytes = b.to_bytes();
    bytes[500] = 0;
    assert!(h.on_datagram(&bytes, 4_000).is_none());
    assert!(h.on_datagram(&bytes[..554], 5_000).is_none());
    let s = h.stats();
    assert_eq!((s.packets, s.malformed, s.short, s.reordered), (3, 1, 1, 1));
    assert!(
        s.last_fault.is_some_and(|f| f.to_string().contains("554")),
        "{s:?}"
    );
    // The hour wrap is not a reordering.
    let mut h = Health::new(HealthConfig::default());
    h.on_packet(&packet(steady(0, 40), 3_599_999_000), 0);
    h.on_packet(&packet(steady(480, 40), 327), 1_327_000);
    let s = h.stats();
    assert_eq!((s.reordered, s.hour_wraps), (0, 1));
}

#[test]
fn blind_sectors_min_range_and_no_returns_are_dropped_and_counted() {
    // Behind the sensor (sensor frame 160..200 deg): azimuth 180 deg clockwise is straight back.
    let blind = [BlindSector {
        from_deg: 160.0,
        to_deg: 200.0,
    }];
    let mut a = assembler(Mount::IDENTITY, &blind);
    let mut p = packet(steady(18_000, 40), 0);
    for b in p.blocks.iter_mut() {
        b.returns[0] = Return {
            distance_2mm: 1000,
            reflectivity: 1,
        };
    }
    let mut q = packet(steady(9_000, 40), 1_327);
    q.blocks[0].returns[0] = Return {
        distance_2mm: 100,
        reflectivity: 1,
    }; // 0.2 m: below 0.5
    q.blocks[0].returns[1] = Return {
        distance_2mm: 60_000,
        reflectivity: 1,
    }; // 120 m: beyond
    q.blocks[0].returns[2] = Return {
        distance_2mm: 1000,
        reflectivity: 1,
    }; // kept
    a.push(&p, 0);
    a.push(&q, 1_327_000);
    let done = a
        .push(&packet(steady(35_950, 40), 2_654), 2_654_000)
        .unwrap_or_else(|| panic!("no revolution"));
    assert_eq!(done.dropped.blind, 12);
    assert_eq!(done.dropped.below_min_range, 1);
    assert_eq!(done.dropped.beyond_max_range, 1);
    assert_eq!(done.points, 1);
    let kept = a.points()[0];
    // Azimuth 90 deg clockwise: the sensor's right, -y.
    assert!(kept.x.abs() < 0.01 && kept.y < -1.9, "{kept:?}");
}

/// The range along the ray from its origin to a vertical cylinder about the sensor's axis.
fn cylinder_range(f: &vlp16::sim::Firing, radius: f64) -> f64 {
    let (o, d) = (f.origin(), f.direction());
    let (a, b) = (d[0] * d[0] + d[1] * d[1], o[0] * d[0] + o[1] * d[1]);
    let c = o[0] * o[0] + o[1] * o[1] - radius * radius;
    (-b + (b * b - a * c).sqrt()) / a
}

#[test]
fn the_emitter_sends_753_packets_a_second_and_a_revolution_sees_a_cylinder() {
    let mount = Mount {
        x_m: 0.3,
        y_m: 0.1,
        z_m: 0.5,
        yaw_rad: 1.0,
    };
    let mut e = Emitter::new(600.0, ReturnMode::Strongest, Calibration::VLP16, 1_000)
        .unwrap_or_else(|err| panic!("{err}"))
        .with_start_azimuth_deg(200.0);
    let mut a = assembler(mount, &[]);
    let mut times = Vec::new();
    let mut revolutions: Vec<(vlp16::scan::ScanDone, Vec<Point>)> = Vec::new();
    e.emit_until(
        1_000_000 + 1_000,
        &mut |f| Some((cylinder_range(&f, 3.0), 50)),
        &mut |bytes, t_us| {
            times.push(t_us);
            let p = DataPacket::decode(bytes).unwrap_or_else(|err| panic!("{err}"));
            if let Some(done) = a.push(&p, t_us * 1000) {
                revolutions.push((done, a.points().to_vec()));
            }
        },
    );
    // One second: 753 or 754 packets, 1.327 ms apart.
    assert!((753..=754).contains(&times.len()), "{}", times.len());
    assert!(
        times
            .windows(2)
            .all(|w| (1_326..=1_328).contains(&(w[1] - w[0])))
    );
    // 10 revolutions in the second; those after the first are complete.
    assert!(revolutions.len() >= 9, "{}", revolutions.len());
    for (done, points) in &revolutions[1..] {
        assert!(done.complete);
        // 0.1 s of firings: 36,166 lasers fired, about 28,900 in 3,617 cycles ... all hit.
        let expected = 0.1e6 / 110.592 * 32.0;
        assert!(
            (points.len() as f64 - expected).abs() < 70.0,
            "{}",
            points.len()
        );
        assert_eq!(done.dropped.total(), 0);
        for p in points {
            let r = (f64::from(p.x) - mount.x_m).hypot(f64::from(p.y) - mount.y_m);
            assert!((r - 3.0).abs() <= 0.002, "{p:?}: {r}");
        }
        let span = done.end_us - done.start_us;
        assert!((99_800..=100_100).contains(&span), "{span}");
    }
}

#[test]
fn dual_return_mode_pairs_blocks_and_drops_duplicates() {
    let mut e = Emitter::new(600.0, ReturnMode::Dual, Calibration::VLP16, 0)
        .unwrap_or_else(|err| panic!("{err}"));
    let mut a = assembler(Mount::IDENTITY, &[]);
    let mut n = 0;
    let mut dones = Vec::new();
    e.emit_until(
        250_000,
        &mut |f| Some((cylinder_range(&f, 2.0), 5)),
        &mut |bytes, t_us| {
            n += 1;
            let p = DataPacket::decode(bytes).unwrap_or_else(|err| panic!("{err}"));
            assert_eq!(p.blocks[0].azimuth_cdeg, p.blocks[1].azimuth_cdeg);
            if let Some(d) = a.push(&p, t_us * 1000) {
                dones.push(d);
            }
        },
    );
    // Twice the packets of single-return mode.
    assert!((376..=378).contains(&n), "{n}");
    let full = dones[1];
    assert!(
        (full.points as f64 - 0.1e6 / 110.592 * 32.0).abs() < 70.0,
        "{full:?}"
    );
    assert_eq!(full.dropped.duplicate as usize, full.points);
}

#[test]
fn deskew_undoes_the_base_motion() {
    // A wall at x = 5 m in the world; the base drives at 1 m/s and turns at 0.5 rad/s; a point
    // fired at time t sees the wall from the base pose at t.
    let (v, w) = (1.0, 0.5);
    let pose = |t: f64| -> (f64, f64, f64) {
        let th = w * t;
        (v / w * th.sin(), v / w * (1.0 - th.cos()), th)
    };
    let mut points = Vec::new();
    for k in 0..100 {
        let t = k as f64 * 0.001;
        let (bx, by, bt) = pose(t);
        let world = (5.0, -0.5 + 0.01 * k as f64);
        let (dx, dy) = (world.0 - bx, world.1 - by);
        let (s, c) = bt.sin_cos();
        points.push(Point {
            x: (c * dx + s * dy) as f32,
            y: (-s * dx + c * dy) as f32,
            z: 0.0,
            t_us: (t * 1e6) as i64,
            intensity: 0,
            laser: 0,
        });
    }
    let t_ref = 100_000;
    deskew(&mut points, v, w, t_ref);
    let (bx, by, bt) = pose(0.1);
    for (k, p) in points.iter().enumerate() {
        let (s, c) = bt.sin_cos();
        let wx = bx + c * f64::from(p.x) - s * f64::from(p.y);
        let wy = by + s * f64::from(p.x) + c * f64::from(p.y);
        assert!(
            (wx - 5.0).abs() < 1e-5 && (wy - (-0.5 + 0.01 * k as f64)).abs() < 1e-5,
            "{k}: {wx} {wy}"
        );
    }
}

#[test]
fn udp_over_loopback_drains_everything_waiting() {
    let mut source = UdpSource::bind("127.0.0.1:0").unwrap_or_else(|e| panic!("{e}"));
    let to = source.local_addr().unwrap_or_else(|e| panic!("{e}"));
    let sender = std::net::UdpSocket::bind("127.0.0.1:0").unwrap_or_else(|e| panic!("{e}"));
    let good = packet(steady(100, 40), 42).to_bytes();
    for _ in 0..20 {
        sender.send_to(&good, to).unwrap_or_else(|e| panic!("{e}"));
    }
    sender
        .send_to(&good[..512], to)
        .unwrap_or_else(|e| panic!("{e}"));
    let mut ok = 0;
    let mut errors = Vec::new();
    // Loopback delivery is immediate, but give the kernel a moment all the same.
    for _ in 0..50 {
        source
            .drain(|r| match r {
                Ok(p) => {
                    assert_eq!(p.timestamp_us, 42);
                    ok += 1;
                }
                Err(e) => errors.push(e),
            })
            .unwrap_or_else(|e| panic!("{e}"));
        if ok + errors.len() == 21 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    assert_eq!(ok, 20);
    assert_eq!(errors, vec![vlp16::PacketError::WrongLength { len: 512 }]);
    assert_eq!((source.datagrams, source.foreign_length), (21, 1));
    assert!(
        source
            .receive_buffer_bytes
            .is_some_and(|b| b >= 75 * PAYLOAD_LEN)
    );
    // Nothing waiting: returns at once.
    assert_eq!(source.drain(|_| {}).ok(), Some(0));
}

/// Only the sensor's address is read once `only_from` names it: a packet from another
/// address (another program on the machine) is dropped unread and counted.
#[test]
fn udp_takes_packets_only_from_the_sensors_address() {
    let mut source = UdpSource::bind("127.0.0.1:0").unwrap_or_else(|e| panic!("{e}"));
    let to = source.local_addr().unwrap_or_else(|e| panic!("{e}"));
    source.only_from("127.0.0.2".parse().unwrap_or_else(|e| panic!("{e}")));
    let sensor = std::net::UdpSocket::bind("127.0.0.2:0").unwrap_or_else(|e| panic!("{e}"));
    let forger = std::net::UdpSocket::bind("127.0.0.1:0").unwrap_or_else(|e| panic!("{e}"));
    let good = packet(steady(100, 40), 42).to_bytes();
    let forged = packet(steady(100, 40), 7).to_bytes();
    for _ in 0..5 {
        forger
            .send_to(&forged, to)
            .unwrap_or_else(|e| panic!("{e}"));
        sensor.send_to(&good, to).unwrap_or_else(|e| panic!("{e}"));
    }
    let mut stamps = Vec::new();
    for _ in 0..50 {
        source
            .drain(|r| stamps.push(r.map(|p| p.timestamp_us)))
            .unwrap_or_else(|e| panic!("{e}"));
        if stamps.len() + source.foreign_sender as usize == 10 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    assert_eq!(stamps, vec![Ok(42); 5]);
    assert_eq!((source.datagrams, source.foreign_sender), (5, 5));
}

fn valid_packet_bytes() -> impl Strategy<Value = Vec<u8>> {
    (
        proptest::collection::vec(any::<u8>(), PAYLOAD_LEN),
        proptest::collection::vec(0u16..36_000, BLOCKS),
        0u32..3_600_000_000,
        0u8..3,
    )
        .prop_map(|(mut bytes, azimuths, ts, mode)| {
            for (k, a) in azimuths.iter().enumerate() {
                bytes[100 * k..100 * k + 2].copy_from_slice(&[0xFF, 0xEE]);
                bytes[100 * k + 2..100 * k + 4].copy_from_slice(&a.to_le_bytes());
            }
            bytes[1200..1204].copy_from_slice(&ts.to_le_bytes());
            bytes[1204] = 0x37 + mode;
            bytes
        })
}

proptest! {
    #[test]
    fn decode_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..1300)) {
        let _ = DataPacket::decode(&bytes);
    }

    #[test]
    fn valid_packets_round_trip_byte_for_byte(bytes in valid_packet_bytes()) {
        let p = DataPacket::decode(&bytes);
        prop_assert!(p.is_ok(), "{:?}", p);
        let mut out = [0u8; PAYLOAD_LEN];
        if let Ok(p) = p {
            p.encode(&mut out);
        }
        prop_assert_eq!(&out[..], &bytes[..]);
    }

    #[test]
    fn the_assembler_keeps_its_capacity_on_any_packet(bytes in valid_packet_bytes(), arrival in any::<u64>()) {
        let mut a = ScanAssembler::new(Calibration::VLP16, Mount::IDENTITY, &[], 100)
            .unwrap_or_else(|e| panic!("{e}"));
        if let Ok(p) = DataPacket::decode(&bytes) {
            for k in 0..3 {
                a.push(&p, arrival.wrapping_add(k));
                prop_assert!(a.points().len() <= 100);
            }
        }
    }
}

#[test]
fn firing_azimuths_match_the_packets_sensor_convention() {
    // A ray fired at azimuth 90 deg clockwise points to the sensor's right (-y).
    let mut e = Emitter::new(600.0, ReturnMode::Strongest, Calibration::VLP16, 0)
        .unwrap_or_else(|err| panic!("{err}"))
        .with_start_azimuth_deg(90.0);
    let mut first = None;
    e.emit_until(
        2_000,
        &mut |f| {
            first.get_or_insert(f);
            None
        },
        &mut |_, _| {},
    );
    let f = first.unwrap_or_else(|| panic!("no firing"));
    assert!((f.azimuth_rad + PI / 2.0).abs() < 1e-9, "{f:?}");
    let d = f.direction();
    assert!(d[1] < -0.9);
}

#[test]
fn the_simulated_sensor_over_loopback_gives_healthy_revolutions() {
    // As in HIL: the simulated sensor sends its packets over loopback UDP; the driver drains
    // them, checks health and assembles revolutions.
    let mut source = UdpSource::bind("127.0.0.1:0").unwrap_or_else(|e| panic!("{e}"));
    let to = source.local_addr().unwrap_or_else(|e| panic!("{e}"));
    let sender = std::net::UdpSocket::bind("127.0.0.1:0").unwrap_or_else(|e| panic!("{e}"));
    let mut emitter = Emitter::new(600.0, ReturnMode::Strongest, Calibration::VLP16, 0)
        .unwrap_or_else(|err| panic!("{err}"));
    let mut health = Health::new(HealthConfig::default());
    let mut scans = assembler(Mount::IDENTITY, &[]);
    let mut revolutions = Vec::new();
    // 0.5 s of simulated time in 10 ms steps: send what the sensor sent, then drain it.
    for step in 1..=50u64 {
        let now_us = step * 10_000;
        emitter.emit_until(
            now_us,
            &mut |f| Some((cylinder_range(&f, 2.5), 30)),
            &mut |bytes, _| {
                sender.send_to(bytes, to).unwrap_or_else(|e| panic!("{e}"));
            },
        );
        let expected = emitter.packets_sent();
        let mut received = 0;
        for _ in 0..100 {
            source
                .drain(|r| {
                    received += 1;
                    let Ok(p) = r else {
                        panic!("a simulated packet did not decode: {r:?}")
                    };
                    health.on_packet(&p, now_us * 1000);
                    if let Some(done) = scans.push(&p, now_us * 1000) {
                        revolutions.push(done);
                    }
                })
                .unwrap_or_else(|e| panic!("{e}"));
            if health.stats().packets == expected {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        assert_eq!(
            health.stats().packets,
            expected,
            "step {step}: {received} this step"
        );
    }
    assert_eq!(
        health.verdict(500_000_000),
        SensorVerdict::Ok,
        "{:?}",
        health.stats()
    );
    assert!(revolutions.len() >= 4, "{revolutions:?}");
    assert!(
        revolutions[1..]
            .iter()
            .all(|r| r.complete && r.points > 28_000)
    );
}
