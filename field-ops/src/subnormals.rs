//! Subnormal floats flushed to zero on the CPU, which the workspace's
//! binaries ask for at start (this library imposes nothing on its users'
//! threads):
//!
//! ```no_run
//! field_ops::subnormals::flush_to_zero();
//! ```
//!
//! A field's gradients reach the subnormal range (below 1.2e-38 in f32)
//! wherever a sample lies far behind a surface: its transmittance is the
//! exponential of minus the density in front of it. x86 CPUs compute with
//! such numbers through a slow microcode assist, so once the field had
//! learnt a surface the reference training step on flex took several times
//! as long on an Intel Xeon (docs/measurements/cpu-step.md).
//! Flushing changes only values below 1.2e-38, which vanish in any f32 sum
//! with a term above about 1e-31.

/// Sets flush-to-zero and denormals-are-zero (x86-64: MXCSR's FTZ and DAZ
/// bits) on the calling thread and on every thread of rayon's global pool,
/// which runs flex's matrix products and element-wise ops. Returns whether
/// this CPU has the switch (x86-64 has it; elsewhere nothing changes).
/// Threads started later outside the pool keep the default.
pub fn flush_to_zero() -> bool {
    rayon::broadcast(|_| set_on_this_thread());
    set_on_this_thread()
}

/// Whether subnormals are flushed on the calling thread.
pub fn flushed_on_this_thread() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        read_mxcsr() & FTZ_DAZ == FTZ_DAZ
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// MXCSR's flush-to-zero (bit 15) and denormals-are-zero (bit 6).
#[cfg(target_arch = "x86_64")]
const FTZ_DAZ: u32 = (1 << 15) | (1 << 6);

#[cfg(target_arch = "x86_64")]
fn read_mxcsr() -> u32 {
    let mut csr = 0u32;
    // SAFETY: `stmxcsr` stores the 32-bit MXCSR register into `csr`, a
    // valid, aligned u32 this function owns; it changes no other state.
    #[allow(unsafe_code)]
    unsafe {
        std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack, preserves_flags));
    }
    csr
}

fn set_on_this_thread() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        let csr = read_mxcsr() | FTZ_DAZ;
        // SAFETY: `ldmxcsr` loads MXCSR from `csr`, a valid u32, which is
        // the current value with FTZ and DAZ set: it changes only how this
        // thread's SSE/AVX arithmetic treats subnormal numbers (no reserved
        // bit is set, so it cannot fault).
        #[allow(unsafe_code)]
        unsafe {
            std::arch::asm!("ldmxcsr [{}]", in(reg) &csr, options(nostack, preserves_flags, readonly));
        }
        true
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
