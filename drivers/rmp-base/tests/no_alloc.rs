//! The driver's steady-state tick allocates nothing: a counting global allocator around
//! `RmpBase::tick` while a base answers on the in-memory bus.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use can_bus::{CanBus, MemoryBus};
use motion_control::Twist;
use rmp_base::{BaseMode, CanLink, RmpBase, RmpBaseConfig, from_can, to_can};
use rmp_codec::feedback::{FeedbackItem, FeedbackLayout, FeedbackSet};
use rmp_codec::v3::{
    ConfigCommand, FirmwareProfile, HostCommand, ModeRequest, NvmFloat, OperationalState,
};

struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);
thread_local! {
    static MEASURING: Cell<bool> = const { Cell::new(false) };
}

// SAFETY: forwards to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if MEASURING.with(|m| m.get()) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if MEASURING.with(|m| m.get()) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn steady_state_tick_does_not_allocate() {
    // The counter itself works: one allocation while measuring is seen.
    MEASURING.with(|m| m.set(true));
    let probe = std::hint::black_box(Box::new(42u64));
    MEASURING.with(|m| m.set(false));
    drop(probe);
    assert_eq!(ALLOCATIONS.swap(0, Ordering::Relaxed), 1);

    let bus = MemoryBus::new();
    let mut base_node = bus.join();
    let config = RmpBaseConfig::default();
    let mut driver = RmpBase::new(CanLink::new(bus.join()), config).unwrap();
    let mut state = OperationalState::Standby;
    let mut layout = FeedbackLayout::ForcedConfig;
    let mut forced = false;
    // The base's stored settings: it keeps what the driver writes.
    let mut nvm = NvmFloat::ALL.map(NvmFloat::default_value);
    let mut now = Duration::ZERO;
    let mut measured_ticks = 0;
    driver.request_mode(BaseMode::Tractor, now);
    for tick in 0..400 {
        if tick >= 100 {
            MEASURING.with(|m| m.set(true));
            measured_ticks += 1;
        }
        driver.set_velocity(Twist::new(0.3, 0.2), now);
        let result = driver.tick(now);
        MEASURING.with(|m| m.set(false));
        result.unwrap();
        // The base: answers in the driver's layout once written.
        while let Some(frame) = base_node.try_recv().unwrap() {
            let raw = from_can(&frame).unwrap();
            if let HostCommand::Config(c) =
                HostCommand::decode(FirmwareProfile::SegwayInc2014, &raw).unwrap()
            {
                match c {
                    ConfigCommand::SetOperationalMode(ModeRequest::Tractor) => {
                        state = OperationalState::Tractor
                    }
                    ConfigCommand::ForceConfigFeedback(on) => forced = on,
                    ConfigCommand::SetFloat(setting, value) => {
                        let index = NvmFloat::ALL.iter().position(|p| *p == setting).unwrap();
                        nvm[index] = value;
                    }
                    _ => {}
                }
            }
            layout = if forced {
                FeedbackLayout::ForcedConfig
            } else {
                FeedbackLayout::User(config.feedback)
            };
            let set = FeedbackSet::from_fn(layout, |item| match item {
                _ if (76..87).contains(&(item as usize)) => nvm[item as usize - 76].to_bits(),
                FeedbackItem::VelocityLimit => nvm[0].to_bits(),
                FeedbackItem::YawRateLimit => nvm[5].to_bits(),
                FeedbackItem::OperationalState => state.to_word(),
                FeedbackItem::UserFeedbackBitmap1 => config.feedback.words()[0],
                FeedbackItem::UserFeedbackBitmap2 => config.feedback.words()[1],
                FeedbackItem::UserFeedbackBitmap3 => config.feedback.words()[2],
                FeedbackItem::UserFeedbackBitmap4 => config.feedback.words()[3],
                FeedbackItem::LinearPosition => (tick as f32 * 0.006).to_bits(),
                _ => 0,
            });
            for f in set.frames() {
                base_node.send(&to_can(&f)).unwrap();
            }
        }
        now += config.command_period;
    }
    assert!(driver.is_driving(), "the loop reached steady state");
    assert!(matches!(layout, FeedbackLayout::User(_)));
    assert!(driver.odometry().x_m > 0.0);
    assert_eq!(measured_ticks, 300);
    assert_eq!(
        ALLOCATIONS.load(Ordering::Relaxed),
        0,
        "allocations in 300 ticks"
    );
}
