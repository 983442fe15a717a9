//! The driver's steady-state tick allocates nothing: a counting global allocator around
//! `RmpBase::tick` while a base answers on the in-memory bus.

use std::time::Duration;

use can_bus::{CanBus, MemoryBus};
use motion_control::Twist;
use rmp_base::{BaseMode, CanLink, RmpBase, RmpBaseConfig, from_can, to_can};
use rmp_codec::feedback::{FeedbackItem, FeedbackLayout, FeedbackSet};
use rmp_codec::v3::{
    ConfigCommand, FirmwareProfile, HostCommand, ModeRequest, NvmFloat, OperationalState,
};

#[global_allocator]
static GLOBAL: test_support::CountingAlloc = test_support::CountingAlloc;

#[test]
fn steady_state_tick_does_not_allocate() {
    // The counter itself works: one allocation while measuring is seen.
    let (probe, n) =
        test_support::allocations_on_this_thread(|| std::hint::black_box(Box::new(42u64)));
    drop(probe);
    assert_eq!(n, 1);
    let mut allocations = 0;

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
        let (result, n) = test_support::allocations_on_this_thread(|| {
            driver.set_velocity(Twist::new(0.3, 0.2), now);
            driver.tick(now)
        });
        if tick >= 100 {
            measured_ticks += 1;
            allocations += n;
        }
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
    assert_eq!(allocations, 0, "allocations in 300 ticks");
}
