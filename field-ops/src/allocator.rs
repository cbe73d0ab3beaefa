//! The allocator the workspace's binaries declare (this library imposes
//! none): jemalloc, where the platform has it.
//!
//! A training step allocates and frees activations of tens of megabytes
//! (65,536 samples x 256 channels x 4 bytes is 64 MiB). glibc serves every
//! block above 32 MiB with its own `mmap` and unmaps it on free, so each
//! step faults all of those pages in again, zeroed by the kernel. jemalloc,
//! configured below, keeps freed pages for the next allocation. A binary opts in with
//!
//! ```no_run
//! #[cfg(not(target_env = "msvc"))]
//! #[global_allocator]
//! static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;
//! ```

#[cfg(not(target_env = "msvc"))]
pub use tikv_jemallocator::Jemalloc;

/// jemalloc's options, read when it starts (`_RJEM_MALLOC_CONF` in the
/// environment adds to them):
/// - `oversize_threshold:0`: blocks above 8 MiB stay in the ordinary arenas
///   (by default they go to one that returns their pages to the OS at once);
/// - `dirty_decay_ms:-1`, `muzzy_decay_ms:-1`: freed pages are kept for the
///   next allocation, never returned (as PyTorch's caching allocator keeps
///   them): the resident memory stays at its peak, and no step pays for
///   faulting the pages in again;
/// - `thp:always`: the kernel backs them with 2 MiB pages where it can, 512
///   times fewer page faults and TLB entries for the same memory.
///
/// What each costs and saves is measured in the README ("Measured here").
#[cfg(not(target_env = "msvc"))]
#[allow(unsafe_code, non_upper_case_globals)]
#[unsafe(export_name = "_rjem_malloc_conf")]
pub static malloc_conf: &[u8; 68] =
    b"oversize_threshold:0,dirty_decay_ms:-1,muzzy_decay_ms:-1,thp:always\0";

/// Returns the pages of freed blocks to the OS, so that the resident size
/// (and a peak measured from here) counts live memory only; what the
/// binaries keep for reuse otherwise stays resident. Does nothing where
/// jemalloc is not built.
pub fn release_freed_pages() {
    #[cfg(not(target_env = "msvc"))]
    {
        let name = c"arena.4096.purge"; // 4096: MALLCTL_ARENAS_ALL
        // SAFETY: `arena.<i>.purge` reads and writes nothing: both pointers
        // are null and both lengths 0, as jemalloc's manual gives it.
        #[allow(unsafe_code)]
        let _ = unsafe {
            tikv_jemalloc_sys::mallctl(
                name.as_ptr(),
                std::ptr::null_mut(),
                std::ptr::null_mut(),
                std::ptr::null_mut(),
                0,
            )
        };
    }
}
