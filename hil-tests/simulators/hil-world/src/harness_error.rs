//! The harness's typed error: what was being done and why, for the library's callers (the
//! `grop` binary and the tests add their own context). A small `Context` trait and `bail!`
//! give the harness code the shape a binary's `anyhow` would, with a typed result.

use std::fmt::Display;

/// Why a step of the HIL harness failed.
#[derive(Debug, thiserror::Error)]
pub enum HarnessError {
    /// A step that failed with a cause: what was being done, and the cause.
    #[error("{what}: {cause}")]
    Step {
        /// What was being done.
        what: String,
        /// Why it failed (the cause's message).
        cause: String,
    },
    /// A step that failed by itself (the message says what and why).
    #[error("{0}")]
    Failed(String),
}

/// Adds what was being done to a failure (a `Result`'s error or an `Option`'s `None`).
pub trait Context<T> {
    /// The failure, as a [`HarnessError`] naming `what`.
    fn context(self, what: impl Display) -> Result<T, HarnessError>;

    /// As [`Context::context`], with the text made only on failure.
    fn with_context<S: Display>(self, what: impl FnOnce() -> S) -> Result<T, HarnessError>;
}

impl<T, E: Display> Context<T> for Result<T, E> {
    fn context(self, what: impl Display) -> Result<T, HarnessError> {
        self.map_err(|e| HarnessError::Step {
            what: what.to_string(),
            cause: e.to_string(),
        })
    }

    fn with_context<S: Display>(self, what: impl FnOnce() -> S) -> Result<T, HarnessError> {
        self.map_err(|e| HarnessError::Step {
            what: what().to_string(),
            cause: e.to_string(),
        })
    }
}

impl<T> Context<T> for Option<T> {
    fn context(self, what: impl Display) -> Result<T, HarnessError> {
        self.ok_or_else(|| HarnessError::Failed(what.to_string()))
    }

    fn with_context<S: Display>(self, what: impl FnOnce() -> S) -> Result<T, HarnessError> {
        self.ok_or_else(|| HarnessError::Failed(what().to_string()))
    }
}

/// Returns a [`HarnessError::Failed`] with the formatted message.
macro_rules! bail {
    ($($arg:tt)*) => {
        return Err($crate::harness_error::HarnessError::Failed(format!($($arg)*)))
    };
}
pub(crate) use bail;

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message
mod tests {
    use super::*;

    fn fails(n: u32) -> Result<u32, HarnessError> {
        if n > 2 {
            bail!("{n} is more than 2");
        }
        "x".parse::<u32>().context(format_args!("parsing for {n}"))
    }

    #[test]
    fn each_failure_says_what_was_being_done_and_why() {
        assert_eq!(fails(3).unwrap_err().to_string(), "3 is more than 2");
        let e = fails(1).unwrap_err().to_string();
        assert!(e.starts_with("parsing for 1: invalid digit"), "{e}");
        let none: Option<u8> = None;
        assert_eq!(
            none.with_context(|| "no stdout").unwrap_err().to_string(),
            "no stdout"
        );
    }
}
