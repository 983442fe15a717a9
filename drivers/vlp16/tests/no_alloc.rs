//! The real-time path allocates nothing after construction: decoding, the health check and the
//! scan assembler over revolutions of packets, with a counting global allocator around them.
#![allow(
    unsafe_code,
    reason = "a counting GlobalAlloc proves the decoder allocates nothing per packet"
)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use vlp16::calib::Calibration;
use vlp16::health::{Health, HealthConfig};
use vlp16::packet::{DataPacket, PAYLOAD_LEN, ReturnMode};
use vlp16::scan::ScanAssembler;
use vlp16::sim::Emitter;
use vlp16::{BlindSector, Mount};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator unchanged, only counting calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn decoding_health_and_assembly_do_not_allocate() {
    // Half a second of packets (5 revolutions at 600 rpm), made before counting.
    let mut emitter = Emitter::new(600.0, ReturnMode::Strongest, Calibration::VLP16, 0)
        .unwrap_or_else(|e| panic!("{e}"));
    let mut stream: Vec<([u8; PAYLOAD_LEN], u64)> = Vec::with_capacity(400);
    emitter.emit_until(
        500_000,
        &mut |f| Some((2.5 / f.direction()[0].hypot(f.direction()[1]), 20)),
        &mut |bytes, t_us| stream.push((*bytes, t_us)),
    );
    let blind = [BlindSector {
        from_deg: 160.0,
        to_deg: 200.0,
    }];
    let mut scans = ScanAssembler::new(Calibration::VLP16, Mount::IDENTITY, &blind, 30_000)
        .unwrap_or_else(|e| panic!("{e}"));
    let mut health = Health::new(HealthConfig::default());

    let before = ALLOCATIONS.load(Ordering::Relaxed);
    let mut revolutions = 0;
    let mut points = 0;
    for (bytes, t_us) in &stream {
        let Ok(packet) = DataPacket::decode(bytes) else {
            continue;
        };
        health.on_packet(&packet, t_us * 1000);
        if scans.push(&packet, t_us * 1000).is_some() {
            revolutions += 1;
            points += scans.points().len();
        }
        let _ = health.verdict(t_us * 1000);
    }
    let allocations = ALLOCATIONS.load(Ordering::Relaxed) - before;
    assert!(
        revolutions >= 4 && points > 100_000,
        "{revolutions} {points}"
    );
    assert_eq!(allocations, 0, "allocations on the packet path");
}
