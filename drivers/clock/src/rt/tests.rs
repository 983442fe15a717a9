//! Tests of the settings, their application and the loop statistics.

use std::time::Duration;

use super::apply::{pin_to_cpu, prefault_stack};
use super::loop_stats::{BUCKETS, bucket_of, bucket_upper_ns};
use super::*;

#[test]
fn specs_parse() {
    assert_eq!(RtSettings::parse("off"), Ok(RtSettings::default()));
    assert_eq!(RtSettings::parse("on"), Ok(RtSettings::ON));
    assert_eq!(
        RtSettings::parse("fifo=50,cpu=1,lock,slack=1"),
        Ok(RtSettings {
            lock_memory: true,
            timer_slack_ns: Some(1),
            fifo_priority: Some(50),
            cpu: Some(1),
            ..RtSettings::OFF
        })
    );
    assert_eq!(
        RtSettings::parse(" on , cpu=0 "),
        Ok(RtSettings {
            cpu: Some(0),
            ..RtSettings::ON
        })
    );
    assert_eq!(
        RtSettings::parse("stack=64K,heap=2M"),
        Ok(RtSettings {
            prefault_stack_bytes: 64 * 1024,
            prefault_heap_bytes: 2 * 1024 * 1024,
            ..RtSettings::OFF
        })
    );
    assert_eq!(
        RtSettings::parse("prefault").map(|s| (s.prefault_stack_bytes, s.prefault_heap_bytes)),
        Ok((DEFAULT_PREFAULT_STACK_BYTES, DEFAULT_PREFAULT_HEAP_BYTES))
    );
    assert!(
        RtSettings::parse("on").is_ok_and(|s| s.cpu.is_none()),
        "on does not pin"
    );
    assert!(RtSettings::parse("off").is_ok_and(|s| s.is_off()));
}

#[test]
fn specs_round_trip_through_display() {
    for spec in [
        "off",
        "on",
        "fifo=10,cpu=3",
        "lock,slack=1000",
        "on,cpu=1",
        "heap=1G",
        "stack=1000,heap=3K",
        "prefault,fifo=2",
    ] {
        let settings = RtSettings::parse(spec).unwrap();
        assert_eq!(settings.to_string(), spec, "shortest form");
        assert_eq!(
            RtSettings::parse(&settings.to_string()),
            Ok(settings),
            "{spec}"
        );
    }
}

#[test]
fn bad_specs_give_named_errors() {
    use RtSpecError as E;
    let err = |s: &str| RtSettings::parse(s).unwrap_err();
    assert_eq!(err(""), E::Empty);
    assert_eq!(err("  "), E::Empty);
    assert_eq!(err("lock,,fifo=5"), E::EmptyItem);
    assert_eq!(err("lock,"), E::EmptyItem);
    assert!(matches!(err("turbo"), E::UnknownItem { item } if item == "turbo"));
    assert!(matches!(err("fifo"), E::MissingValue { key } if key == "fifo"));
    assert!(matches!(err("cpu="), E::MissingValue { .. }));
    assert!(matches!(err("lock=1"), E::UnexpectedValue { key } if key == "lock"));
    assert!(matches!(err("on=1"), E::UnexpectedValue { .. }));
    assert!(matches!(err("fifo=1,fifo=2"), E::Duplicate { key } if key == "fifo"));
    assert!(matches!(err("fifo=high"), E::BadNumber { .. }));
    assert!(matches!(err("fifo=-1"), E::BadNumber { .. }));
    assert!(matches!(err("fifo=0"), E::OutOfRange { value: 0, .. }));
    assert!(matches!(
        err("fifo=100"),
        E::OutOfRange {
            value: 100,
            max: 99,
            ..
        }
    ));
    assert!(matches!(err("slack=0"), E::OutOfRange { .. }));
    assert!(matches!(err("cpu=1024"), E::OutOfRange { .. }));
    assert!(matches!(err("heap=2G"), E::OutOfRange { .. }));
    assert!(matches!(err("heap=12Q"), E::BadNumber { .. }));
    assert!(matches!(err("stack=K"), E::BadNumber { .. }));
    assert!(matches!(
        err("heap=99999999999999999999G"),
        E::BadNumber { .. }
    ));
    // Every error says what it is about.
    for bad in ["", "x", "fifo", "lock=1", "fifo=0", "cpu=z"] {
        assert!(!err(bad).to_string().is_empty());
    }
}

#[test]
fn percentiles_of_known_samples() {
    let mut s = LoopStats::new(Duration::from_millis(20));
    assert_eq!(s.percentile(50.0), None);
    assert_eq!(s.summary().count, 0);
    // 1..=100 us.
    for us in 1..=100u64 {
        s.record(
            Duration::from_secs(1),
            Duration::from_secs(1) + Duration::from_micros(us),
        );
    }
    let at = |p| s.percentile(p).unwrap().as_micros();
    // Buckets are [n, n+1) us, reported by their upper edge, capped at the maximum.
    assert_eq!(at(50.0), 51);
    assert_eq!(at(99.0), 100);
    assert_eq!(at(100.0), 100);
    assert_eq!(at(0.0), 2);
    let sum = s.summary();
    assert_eq!(sum.count, 100);
    assert_eq!(sum.max, Duration::from_micros(100));
    assert_eq!(sum.mean, Duration::from_nanos(50_500));
    assert!(sum.p50 <= sum.p99 && sum.p99 <= sum.p999 && sum.p999 <= sum.max);
}

#[test]
fn coarse_and_overflow_buckets_and_counters() {
    let mut s = LoopStats::new(Duration::from_millis(2));
    s.record_lateness_ns(5_000); // 5 us
    s.record_lateness_ns(3_456_000); // 3.456 ms: coarse bucket 3.4..3.5 ms
    s.record_lateness_ns(250_000_000); // 250 ms: overflow bucket
    assert_eq!(s.percentile(33.0), Some(Duration::from_micros(6)));
    assert_eq!(s.percentile(60.0), Some(Duration::from_micros(3_500)));
    assert_eq!(s.percentile(99.0), Some(Duration::from_millis(250)));
    // Early wake-ups count as on time.
    s.record(Duration::from_secs(2), Duration::from_secs(1));
    assert_eq!(s.summary().early, 1);
    assert!(!s.record_end(Duration::from_millis(10), Duration::from_millis(12)));
    assert!(s.record_end(Duration::from_millis(13), Duration::from_millis(12)));
    s.record_overrun();
    assert_eq!(s.overruns(), 2);
    assert_eq!(s.count(), 4);
    s.reset();
    assert_eq!(s.count(), 0);
    assert_eq!(s.period(), Duration::from_millis(2));
    // Extreme values do not overflow anything.
    s.record(Duration::ZERO, Duration::MAX);
    assert_eq!(s.percentile(50.0), Some(Duration::from_nanos(u64::MAX)));
    assert_eq!(s.percentile(f64::NAN), Some(s.max()));
    assert_eq!(s.percentile(-3.0), Some(s.max()));
}

#[test]
fn bucket_edges_are_consistent() {
    for ns in [
        0, 999, 1000, 1_999_999, 2_000_000, 2_099_999, 2_100_000, 99_999_999,
    ] {
        let b = bucket_of(ns);
        assert!(ns < bucket_upper_ns(b), "{ns} in bucket {b}");
        if b > 0 {
            assert!(ns >= bucket_upper_ns(b - 1), "{ns} above bucket {}", b - 1);
        }
    }
    assert_eq!(bucket_of(100_000_000), BUCKETS - 1);
    assert_eq!(bucket_of(u64::MAX), BUCKETS - 1);
}

#[test]
fn applying_nothing_reports_nothing() {
    let report = apply(&RtSettings::OFF);
    assert!(report.all_applied());
    assert_eq!(report.to_string().lines().count(), 6);
    assert!(report.to_string().lines().all(|l| l.ends_with(": off")));
}

/// Steps that never need privileges: timer slack, a bounded stack pre-fault, a small heap
/// pre-fault. Run on a thread of its own so the test runner's thread keeps its settings.
#[test]
fn unprivileged_steps_apply_on_a_thread() {
    let report = std::thread::spawn(|| {
        apply(&RtSettings {
            timer_slack_ns: Some(1),
            prefault_stack_bytes: 64 * 1024,
            prefault_heap_bytes: 1024 * 1024,
            ..RtSettings::OFF
        })
    })
    .join()
    .unwrap();
    assert!(report.applied(RtStep::TimerSlack), "{report}");
    assert!(report.applied(RtStep::PrefaultStack), "{report}");
    assert!(report.applied(RtStep::PrefaultHeap), "{report}");
    assert!(!report.applied(RtStep::SchedFifo));
    // A stack pre-fault bigger than the stack is clamped, not a crash.
    let big = std::thread::Builder::new()
        .stack_size(256 * 1024)
        .spawn(|| prefault_stack(64 * 1024 * 1024))
        .unwrap()
        .join()
        .unwrap();
    assert!(
        matches!(&big, RtOutcome::Applied(t) if t.contains("left")),
        "{big:?}"
    );
}

/// Whatever the privileges, FIFO and affinity give an outcome and a line each, never a
/// panic; a refusal names the call and says what to do.
#[test]
fn privileged_steps_report_either_way() {
    let report = std::thread::spawn(|| {
        apply(&RtSettings {
            fifo_priority: Some(1),
            cpu: Some(MAX_CPU_INDEX),
            ..RtSettings::OFF
        })
    })
    .join()
    .unwrap();
    let text = report.to_string();
    assert!(text.contains("SCHED_FIFO: "), "{text}");
    if let RtOutcome::Refused(r) = report.outcome(RtStep::SchedFifo) {
        assert!(
            r.to_string().contains("CAP_SYS_NICE") || r.errno != libc::EPERM,
            "{r}"
        );
    }
    // No machine here has 1024 CPUs in its cpuset.
    if let RtOutcome::Refused(r) = report.outcome(RtStep::CpuAffinity) {
        assert!(r.to_string().contains("sched_setaffinity"), "{r}");
    }
    assert!(matches!(
        pin_to_cpu(MAX_CPU_INDEX + 1),
        RtOutcome::Refused(_)
    ));
}

#[test]
fn refusals_read_well() {
    let r = RtRefusal {
        call: "sched_setscheduler(SCHED_FIFO, 50)".into(),
        errno: libc::EPERM,
        advice: "run as root or grant CAP_SYS_NICE".into(),
    };
    let text = r.to_string();
    assert!(text.contains("(EPERM: Operation not permitted"), "{text}");
    assert!(
        text.ends_with("run as root or grant CAP_SYS_NICE"),
        "{text}"
    );
}
