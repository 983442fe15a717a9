//! The machine a report was measured on, from /proc and /sys (unknown fields say so).
#![allow(
    unsafe_code,
    reason = "libc::geteuid: whether the real-time settings can be tried"
)]

use std::time::{SystemTime, UNIX_EPOCH};

/// What the report says about the machine.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineInfo {
    /// CPU model name (/proc/cpuinfo).
    pub cpu_model: String,
    /// CPUs this process may run on.
    pub cpus: usize,
    /// Kernel release (/proc/sys/kernel/osrelease).
    pub kernel: String,
    /// Kernel build string (/proc/sys/kernel/version), which names PREEMPT / PREEMPT_RT.
    pub kernel_version: String,
    /// Preemption model: `PREEMPT_RT` (/sys/kernel/realtime or the build string),
    /// `PREEMPT_DYNAMIC`, `PREEMPT`, or `none/voluntary`.
    pub preemption: String,
    /// The process's default timer slack (/proc/self/timerslack_ns), ns.
    pub timer_slack_ns: Option<u64>,
    /// The kernel's real-time throttling: runtime per period (/proc/sys/kernel/sched_rt_*).
    pub rt_throttle: String,
    /// Load average over 1 min when the measurement started (/proc/loadavg).
    pub loadavg_1min: Option<f64>,
    /// Effective user id 0.
    pub root: bool,
    /// Date, UTC, `YYYY-MM-DD HH:MM`.
    pub date_utc: String,
}

fn read(path: &str) -> Option<String> {
    std::fs::read_to_string(path)
        .ok()
        .map(|s| s.trim().to_owned())
}

impl MachineInfo {
    /// Reads it now.
    pub fn now() -> Self {
        let cpu_model = read("/proc/cpuinfo")
            .and_then(|info| {
                info.lines()
                    .find(|l| l.starts_with("model name"))
                    .and_then(|l| l.split_once(':'))
                    .map(|(_, v)| v.trim().to_owned())
            })
            .unwrap_or_else(|| "unknown".to_owned());
        let kernel = read("/proc/sys/kernel/osrelease").unwrap_or_else(|| "unknown".into());
        let kernel_version = read("/proc/sys/kernel/version").unwrap_or_else(|| "unknown".into());
        let realtime = read("/sys/kernel/realtime").is_some_and(|s| s == "1");
        let preemption = if realtime || kernel_version.contains("PREEMPT_RT") {
            "PREEMPT_RT"
        } else if kernel_version.contains("PREEMPT_DYNAMIC") {
            "PREEMPT_DYNAMIC"
        } else if kernel_version.contains("PREEMPT") {
            "PREEMPT"
        } else {
            "none/voluntary"
        }
        .to_owned();
        let rt_throttle = match (
            read("/proc/sys/kernel/sched_rt_runtime_us"),
            read("/proc/sys/kernel/sched_rt_period_us"),
        ) {
            (Some(runtime), Some(period)) => format!("{runtime} us of every {period} us"),
            _ => "unknown".to_owned(),
        };
        Self {
            cpu_model,
            cpus: std::thread::available_parallelism().map_or(0, |n| n.get()),
            kernel,
            kernel_version,
            preemption,
            timer_slack_ns: read("/proc/self/timerslack_ns").and_then(|s| s.parse().ok()),
            rt_throttle,
            loadavg_1min: read("/proc/loadavg")
                .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok())),
            // SAFETY: geteuid has no preconditions.
            root: unsafe { libc::geteuid() } == 0,
            date_utc: utc_now(),
        }
    }
}

/// The current UTC date and time, `YYYY-MM-DD HH:MM`.
pub fn utc_now() -> String {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    format_utc(secs)
}

/// Seconds since the epoch as `YYYY-MM-DD HH:MM` (UTC; Howard Hinnant's civil-from-days).
pub fn format_utc(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02} {:02}:{:02}",
        rem / 3600,
        (rem % 3600) / 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates() {
        assert_eq!(format_utc(0), "1970-01-01 00:00");
        assert_eq!(format_utc(951_782_400), "2000-02-29 00:00");
        assert_eq!(format_utc(1_767_225_600 + 3_660), "2026-01-01 01:01");
    }

    #[test]
    fn reads_this_machine() {
        let m = MachineInfo::now();
        assert!(m.cpus >= 1);
        assert!(!m.kernel.is_empty());
        assert_eq!(m.date_utc.len(), 16);
    }
}
