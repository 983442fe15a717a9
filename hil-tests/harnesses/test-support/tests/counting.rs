//! The counter counts: an allocation made while counting is seen, one made outside is not, and
//! another thread's allocations count only in the every-thread form.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use test_support::{CountingAlloc, allocations_by_any_thread, allocations_on_this_thread};

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

#[test]
fn allocations_are_counted_where_they_are_asked_for() {
    let (boxed, n) = allocations_on_this_thread(|| std::hint::black_box(Box::new(7u64)));
    assert_eq!(n, 1);
    drop(boxed);
    let (_, n) = allocations_on_this_thread(|| std::hint::black_box(1 + 1));
    assert_eq!(n, 0);
    // Another thread's allocation is not this thread's ...
    let (_, n) = allocations_on_this_thread(|| {
        std::thread::spawn(|| drop(std::hint::black_box(vec![1u8; 64])))
            .join()
            .unwrap();
    });
    let spawn_cost = n;
    let (_, n_any) = allocations_by_any_thread(|| {
        std::thread::spawn(|| drop(std::hint::black_box(vec![1u8; 64])))
            .join()
            .unwrap();
    });
    // ... but counts among every thread's (the spawn itself allocates too).
    assert!(n_any > spawn_cost, "{n_any} vs {spawn_cost}");
}
