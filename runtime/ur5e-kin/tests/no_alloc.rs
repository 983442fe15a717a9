//! `plan_place` and IK allocate nothing: a counting global allocator around the calls.
#![allow(
    unsafe_code,
    reason = "a counting GlobalAlloc proves the kinematics allocate nothing"
)]

use core::f64::consts::FRAC_PI_2;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::{Point3, Vector3};
use ur5e_kin::{BasePose, ObstacleBox, PlaceConfig, Ur5e, arm_collides, plan_place};

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
fn placement_and_ik_do_not_allocate() {
    let cfg = PlaceConfig::default();
    let arm = Ur5e::default();
    let obstacles = vec![
        ObstacleBox::from_min_max(Point3::new(-1.5, 5.8, 0.0), Point3::new(1.5, 6.2, 1.0)),
        ObstacleBox {
            center: Point3::new(0.5, 5.0, 0.45),
            half_extents: Vector3::new(0.225, 0.225, 0.45),
            yaw_rad: 0.3,
        },
    ];
    let goal = Point3::new(0.0, 6.0, 1.3);
    let poses: Vec<BasePose> = [0.5, 0.7, 0.9, 1.1, 1.3]
        .iter()
        .map(|off| BasePose {
            x_m: 0.1,
            y_m: 6.0 - off,
            yaw_rad: FRAC_PI_2,
        })
        .collect();
    let q = [0.4, -1.2, 1.1, -1.3, 1.0, 0.6];
    let flange = arm.forward(&q);

    let before = ALLOCATIONS.load(Ordering::Relaxed);
    let mut outcomes = 0usize;
    for base in &poses {
        outcomes += plan_place(&cfg, *base, goal, &obstacles).is_ok() as usize;
        outcomes += arm_collides(&cfg, *base, &q, &obstacles) as usize;
    }
    outcomes += arm.inverse(&flange).len();
    let after = ALLOCATIONS.load(Ordering::Relaxed);
    assert_eq!(after - before, 0, "allocations in the placement path");
    assert!(outcomes > 0);
}
