//! Control laws: rate/acceleration limiter, watchdog, mode state machines, path follower (no_std, no heap).
