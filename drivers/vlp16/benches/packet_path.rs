//! The packet path's cost (docs/lidar.md): decoding one packet, the health check and the scan
//! assembler over a second of packets, and a revolution (76 packets at 600 rpm) from bytes to
//! base-frame points.
//! `cargo bench -p vlp16 --bench packet_path`.

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use vlp16::calib::Calibration;
use vlp16::health::{Health, HealthConfig};
use vlp16::packet::{DataPacket, PAYLOAD_LEN, ReturnMode};
use vlp16::scan::ScanAssembler;
use vlp16::sim::Emitter;
use vlp16::{BlindSector, Mount};

/// One second of packets of a sensor in a 3 m round room, with their send times.
fn stream() -> Vec<([u8; PAYLOAD_LEN], u64)> {
    let mut emitter = Emitter::new(600.0, ReturnMode::Strongest, Calibration::VLP16, 0)
        .unwrap_or_else(|e| panic!("{e}"));
    let mut out = Vec::new();
    emitter.emit_until(
        1_000_000,
        &mut |f| {
            let d = f.direction();
            Some((3.0 / d[0].hypot(d[1]), 40))
        },
        &mut |bytes, t_us| out.push((*bytes, t_us)),
    );
    out
}

fn bench(c: &mut Criterion) {
    let packets = stream();
    let mount = Mount {
        x_m: 0.2,
        y_m: 0.0,
        z_m: 0.45,
        yaw_rad: 0.0,
    };
    let blind = [BlindSector {
        from_deg: 160.0,
        to_deg: 200.0,
    }];
    c.bench_function("decode one packet", |b| {
        b.iter(|| DataPacket::decode(black_box(&packets[10].0)))
    });
    let decoded: Vec<(DataPacket, u64)> = packets
        .iter()
        .filter_map(|(bytes, t)| DataPacket::decode(bytes).ok().map(|p| (p, *t)))
        .collect();
    // Each of the following starts from a fresh health check and assembler (made outside the
    // timing), since a second lap over the same packets would read as reordered.
    c.bench_function("health on a second of packets (753)", |b| {
        b.iter_batched(
            || Health::new(HealthConfig::default()),
            |mut health| {
                for (p, t) in &decoded {
                    health.on_packet(black_box(p), t * 1000);
                }
                health
            },
            BatchSize::LargeInput,
        )
    });
    let fresh = || {
        ScanAssembler::new(Calibration::VLP16, mount, &blind, 30_000)
            .unwrap_or_else(|e| panic!("{e}"))
    };
    c.bench_function("assemble a second of packets (753 x 384 returns)", |b| {
        b.iter_batched(
            fresh,
            |mut scans| {
                for (p, t) in &decoded {
                    black_box(scans.push(black_box(p), t * 1000));
                }
                scans
            },
            BatchSize::LargeInput,
        )
    });
    c.bench_function(
        "a revolution from bytes (76 packets: decode, health, assemble)",
        |b| {
            b.iter_batched(
                || (fresh(), Health::new(HealthConfig::default())),
                |(mut scans, mut health)| {
                    for (bytes, t) in &packets[..76] {
                        if let Some(p) = health.on_datagram(black_box(bytes), t * 1000) {
                            black_box(scans.push(&p, t * 1000));
                        }
                    }
                    (scans, health)
                },
                BatchSize::LargeInput,
            )
        },
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
