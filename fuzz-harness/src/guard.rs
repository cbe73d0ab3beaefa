//! The allocation cap and the hang watchdog of one worker process.
//!
//! [`CountingAlloc`] (installed as the global allocator of the
//! `fuzz-harness` binary) counts what the fuzzing thread allocates while an
//! execution is armed: a single request or the live total above the cap
//! is a defect. It cannot fail the allocation (the standard library aborts
//! on a null return, and an allocator must not unwind), so the offending
//! thread records the request and sleeps; the watchdog thread sees the
//! record, reports it on stdout and ends the worker, and the supervisor
//! starts a new worker after the failing execution. A hang is found the
//! same way: an execution armed for longer than the time limit.

// A global allocator is an `unsafe impl` by definition; the unsafe code is
// limited to forwarding to the system allocator.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Write;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// Exit status of a worker ended by the watchdog (the defect is on stdout).
pub const EXIT_DEFECT: i32 = 86;

thread_local! {
    /// Whether this thread is inside an armed execution.
    static ARMED: Cell<bool> = const { Cell::new(false) };
    /// Bytes allocated minus bytes freed by this thread since arming.
    static LIVE: Cell<i64> = const { Cell::new(0) };
}

/// The cap of the armed execution, bytes.
static CAP: AtomicU64 = AtomicU64::new(u64::MAX);
/// The request that broke the cap (0: none).
static OVER_CAP: AtomicU64 = AtomicU64::new(0);
/// Whether the request was one allocation (false: the live total).
static OVER_SINGLE: AtomicBool = AtomicBool::new(false);
/// Index of the armed execution (`u64::MAX`: none).
static CURRENT: AtomicU64 = AtomicU64::new(u64::MAX);
/// Sequence number of executions, so the watchdog tells a new one from a
/// long one.
static SEQUENCE: AtomicU64 = AtomicU64::new(0);

/// The system allocator, counting the armed thread's requests.
pub struct CountingAlloc;

/// Counts `grow` bytes (negative: freed) for the armed thread; returns
/// whether the request may go ahead.
fn account(request: usize, grow: i64) -> bool {
    let armed = ARMED.try_with(Cell::get).unwrap_or(false);
    if !armed {
        return true;
    }
    let live = LIVE.try_with(|l| {
        let v = l.get() + grow;
        l.set(v);
        v
    });
    let cap = CAP.load(Ordering::Relaxed);
    let single = request as u64 > cap;
    let total = live.is_ok_and(|v| v > 0 && v as u64 > cap);
    if !(single || total) {
        return true;
    }
    OVER_SINGLE.store(single, Ordering::SeqCst);
    let bytes = if single {
        request as u64
    } else {
        live.unwrap_or(0) as u64
    };
    OVER_CAP.store(bytes.max(1), Ordering::SeqCst);
    // Neither failing nor unwinding is allowed here: wait for the watchdog
    // to report the defect and end the process.
    loop {
        std::thread::sleep(Duration::from_secs(60));
    }
}

// SAFETY: every method forwards to `System` with the caller's layout and
// pointer unchanged; the accounting touches only atomics and const
// thread-locals, which do not allocate.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        account(layout.size(), layout.size() as i64);
        // SAFETY: the caller's layout contract is passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        account(layout.size(), layout.size() as i64);
        // SAFETY: as for `alloc`.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if ARMED.try_with(Cell::get).unwrap_or(false) {
            let _ = LIVE.try_with(|l| l.set(l.get() - layout.size() as i64));
        }
        // SAFETY: `ptr` was allocated by `System` with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        account(new_size, new_size as i64 - layout.size() as i64);
        // SAFETY: `ptr` was allocated by `System` with `layout`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// The allocation cap for an input of `len` bytes: 64 MiB or 64 times the
/// input, whichever is larger (room for parsing into wider types and for
/// the loaders' own tables, far below what a lying header announces).
pub fn cap_for(len: usize) -> u64 {
    (64u64 << 20).max(64 * len as u64)
}

/// Arms the current thread for execution `index` with `cap` bytes.
pub fn arm(index: u64, cap: u64) {
    CAP.store(cap, Ordering::SeqCst);
    LIVE.with(|l| l.set(0));
    SEQUENCE.fetch_add(1, Ordering::SeqCst);
    CURRENT.store(index, Ordering::SeqCst);
    ARMED.with(|a| a.set(true));
}

/// Ends the armed execution of the current thread.
pub fn disarm() {
    ARMED.with(|a| a.set(false));
    CURRENT.store(u64::MAX, Ordering::SeqCst);
}

/// Starts the watchdog: every few milliseconds it checks for a broken cap
/// and for an execution armed longer than `limit`, and on either prints
/// the defect line (`alloc INDEX BYTES single|live` or `hang INDEX MS`)
/// and ends the process with [`EXIT_DEFECT`].
pub fn start_watchdog(limit: Duration) {
    std::thread::spawn(move || {
        let mut seen = (u64::MAX, Instant::now());
        loop {
            std::thread::sleep(Duration::from_millis(5));
            let index = CURRENT.load(Ordering::SeqCst);
            let over = OVER_CAP.load(Ordering::SeqCst);
            if over != 0 {
                let how = if OVER_SINGLE.load(Ordering::SeqCst) {
                    "single"
                } else {
                    "live"
                };
                report(format_args!("alloc {index} {over} {how}"));
            }
            let seq = SEQUENCE.load(Ordering::SeqCst);
            if index == u64::MAX || seq != seen.0 {
                seen = (seq, Instant::now());
                continue;
            }
            let ms = seen.1.elapsed().as_millis();
            if ms > limit.as_millis() {
                report(format_args!("hang {index} {ms}"));
            }
        }
    });
}

fn report(line: std::fmt::Arguments<'_>) -> ! {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
    std::process::exit(EXIT_DEFECT);
}
