//! `LoopStats` allocates nothing after construction: recording, percentiles and summaries run
//! under a counting global allocator that counts this thread's allocations.

use std::time::Duration;

use grop_clock::rt::LoopStats;

#[global_allocator]
static GLOBAL: test_support::CountingAlloc = test_support::CountingAlloc;

fn allocations() -> u64 {
    test_support::this_thread_allocations()
}

#[test]
fn loop_stats_allocate_nothing_after_construction() {
    test_support::count_this_thread(true);
    let period = Duration::from_millis(2);
    let mut stats = LoopStats::new(period);
    // The counter itself works.
    let before = allocations();
    drop(std::hint::black_box(vec![1u8; 16]));
    assert!(
        allocations() > before,
        "the counting allocator is installed"
    );

    let before = allocations();
    let mut deadline = Duration::from_secs(1);
    let mut checksum = Duration::ZERO;
    for i in 0..100_000u64 {
        // Lateness spread over every bucket range: fine, coarse and overflow.
        let late = Duration::from_nanos((i * 7919) % 150_000_000);
        stats.record(deadline, deadline + late);
        stats.record_end(
            deadline + late + Duration::from_micros(50),
            deadline + period,
        );
        if i % 1000 == 0 {
            checksum += stats.percentile(99.0).unwrap_or_default();
            checksum += stats.summary().p50;
        }
        deadline += period;
    }
    let summary = stats.summary();
    let during = allocations() - before;
    assert_eq!(during, 0, "LoopStats allocated {during} times");
    assert_eq!(summary.count, 100_000);
    assert!(summary.p50 <= summary.p99 && summary.p99 <= summary.max);
    assert!(checksum > Duration::ZERO);
}
