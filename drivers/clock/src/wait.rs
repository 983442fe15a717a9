//! Waiting on file descriptors with a timeout finer than the scheduler tick (`ppoll`): the one
//! wrapper the buses and the iceoryx2 topics use to sleep until a message or a deadline.
#![allow(
    unsafe_code,
    reason = "ppoll through libc: the wait on sockets, eventfds and iceoryx2 listeners"
)]

use std::time::Duration;

/// Most descriptors one wait watches.
pub const MAX_WAIT_FDS: usize = 8;

/// Sleeps until one of `fds` is readable or `timeout` has passed (ppoll: no rounding to
/// scheduler ticks). Descriptors beyond [`MAX_WAIT_FDS`] are not watched. An interrupted sleep
/// returns early with `Ok`: the caller loops on its own deadline.
pub fn wait_readable(fds: &[i32], timeout: Duration) -> std::io::Result<()> {
    let mut poll_fds = [libc::pollfd {
        fd: -1,
        events: libc::POLLIN,
        revents: 0,
    }; MAX_WAIT_FDS];
    let n = fds.len().min(MAX_WAIT_FDS);
    for (slot, fd) in poll_fds.iter_mut().zip(fds) {
        slot.fd = *fd;
    }
    let timeout = libc::timespec {
        tv_sec: libc::time_t::try_from(timeout.as_secs()).unwrap_or(libc::time_t::MAX),
        // Below 1e9, so it fits a c_long on every target.
        tv_nsec: timeout.subsec_nanos() as libc::c_long,
    };
    // SAFETY: `n` valid pollfds (at most MAX_WAIT_FDS, the array's length), a valid timespec,
    // no signal mask change.
    let status = unsafe {
        libc::ppoll(
            poll_fds.as_mut_ptr(),
            n as libc::nfds_t,
            &timeout,
            std::ptr::null(),
        )
    };
    if status < 0 {
        let error = std::io::Error::last_os_error();
        if error.kind() != std::io::ErrorKind::Interrupted {
            return Err(error);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    #[test]
    fn a_wait_on_nothing_readable_lasts_its_timeout_and_a_readable_fd_ends_it() {
        let mut fds = [0i32; 2];
        // SAFETY: `fds` has room for the two descriptors pipe writes.
        assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
        let t0 = Instant::now();
        wait_readable(&[fds[0]], Duration::from_millis(30)).unwrap();
        assert!(
            t0.elapsed() >= Duration::from_millis(25),
            "{:?}",
            t0.elapsed()
        );
        // SAFETY: writes one byte from a valid buffer to the pipe's write end.
        assert_eq!(unsafe { libc::write(fds[1], [1u8].as_ptr().cast(), 1) }, 1);
        let t0 = Instant::now();
        wait_readable(&[fds[0]], Duration::from_secs(10)).unwrap();
        assert!(t0.elapsed() < Duration::from_secs(5));
        // SAFETY: closes the two descriptors pipe opened.
        unsafe {
            libc::close(fds[0]);
            libc::close(fds[1]);
        }
    }
}
