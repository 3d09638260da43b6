//! Advice to the kernel to back a large buffer with transparent huge pages.

/// Ask for huge pages on the whole pages inside `[ptr, ptr + len)`, before the buffer is
/// first touched: the kernel then faults (and zeroes) 2 MB at a time instead of 4 kB. Only
/// advice: a no-op off Linux, and an error from the kernel is ignored.
pub(super) fn advise(ptr: *mut u8, len: usize) {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: sysconf reads a system setting and touches no memory of ours.
        let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
        let page = if page > 0 { page as usize } else { 4096 };
        let start = (ptr as usize).div_ceil(page) * page;
        let end = (ptr as usize + len) / page * page;
        if end > start + (2 << 20) {
            // SAFETY: the range lies inside one live allocation of ours; madvise with
            // MADV_HUGEPAGE changes how its pages are backed, never their contents.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (ptr, len);
}
