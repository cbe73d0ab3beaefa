//! Vectorised `f32` sine and exponential (a change to the vendored crate:
//! `VENDORED.md`).
//!
//! The scalar loops called libm's `sinf` and `expf` once per element on one
//! thread; the integrated positional encoding takes both of every encoded
//! feature of every sample, which made them the largest elementwise cost
//! of a training step. Both functions here reduce the argument by the
//! nearest multiple of a constant (Cody and Waite: the constant split in
//! parts short enough that their products with the multiple are exact),
//! evaluate a polynomial on the remainder and fold the multiple back in
//! with bit operations. All of it is branch-free, so the loops vectorise
//! at every instruction set `macerator` dispatches to.
//!
//! - sine: the remainder of a multiple of pi, in `[-pi/2, pi/2]`, an odd
//!   polynomial of degree 11 (fitted to within 2e-11 of the sine there);
//!   the multiple's parity gives the sign. Arguments of magnitude up to
//!   [`SIN_FAST_LIMIT`], within 2.5e-7 of the float64 sine.
//! - exponential: `2^k e^r` with `|r| <= ln(2) / 2` and Cephes' polynomial
//!   for `e^r`; arguments in `[-87, 88]`, within 2.5e-7 relative of the
//!   float64 exponential, and below `-104` (exactly 0, as libm).
//!
//! Other arguments (larger ones, those whose results are subnormal or
//! overflow, infinities and NaN) go through libm, a block of [`BLOCK`]
//! elements at a time, so their results are exactly what they were.

use macerator::Simd;

#[cfg(feature = "rayon")]
use rayon::prelude::*;

/// The largest argument magnitude the polynomial path takes (`2^17`): the
/// multiple of pi then has at most 16 bits, and its products with the first
/// two parts of pi (8 significant bits each) are exact.
pub const SIN_FAST_LIMIT: f32 = 131_072.0;

/// Elements checked against the fast paths' ranges together.
pub const BLOCK: usize = 64;

/// Both functions are compute-bound: a few thousand elements a thread already
/// outweigh the cost of spreading them over the pool.
#[cfg(feature = "rayon")]
const PARALLEL_THRESHOLD: usize = 1 << 16;

#[cfg(feature = "rayon")]
const CHUNK_SIZE: usize = 1 << 14;

/// `1.5 * 2^23`: adding it rounds a float of magnitude below `2^22` to the
/// nearest integer, kept in the low bits of the sum's mantissa.
const ROUND_MAGIC: f32 = 12_582_912.0;
const PI_A: f32 = 3.140_625;
const PI_B: f32 = 9.651_184_082_031_25e-4;
const PI_C: f32 = 2.535_181_7e-6;
const S3: f32 = -1.666_666_666e-1;
const S5: f32 = 8.333_330_42e-3;
const S7: f32 = -1.984_079_64e-4;
const S9: f32 = 2.752_230_07e-6;
const S11: f32 = -2.384_194_14e-8;

/// The sine of `x`, `|x| <= SIN_FAST_LIMIT`.
#[inline(always)]
fn sin_reduced(x: f32) -> f32 {
    let shifted = x * core::f32::consts::FRAC_1_PI + ROUND_MAGIC;
    let n = shifted - ROUND_MAGIC;
    // The mantissa's lowest bit is the parity of `n` (ROUND_MAGIC is even):
    // sin(r + n pi) = (-1)^n sin(r).
    let sign = shifted.to_bits() << 31;
    let r = ((x - n * PI_A) - n * PI_B) - n * PI_C;
    let r2 = r * r;
    let q = (((S11 * r2 + S9) * r2 + S7) * r2 + S5) * r2 + S3;
    // r (1 + r^2 q) rather than r + r^3 q: sin(-0) stays -0.
    let s = r * (1.0 + r2 * q);
    f32::from_bits(s.to_bits() ^ sign)
}

/// `a[i] = sin(a[i])` for every element.
#[inline]
pub fn sin_inplace_f32(a: &mut [f32]) {
    #[cfg(feature = "rayon")]
    if a.len() >= PARALLEL_THRESHOLD {
        a.par_chunks_mut(CHUNK_SIZE).for_each(sin_inplace_f32_seq);
        return;
    }
    sin_inplace_f32_seq(a);
}

#[macerator::with_simd]
fn sin_inplace_f32_seq<S: Simd>(a: &mut [f32]) {
    for block in a.chunks_mut(BLOCK) {
        let fast = block
            .iter()
            .fold(true, |fast, &x| fast & (x.abs() <= SIN_FAST_LIMIT));
        if fast {
            for x in block.iter_mut() {
                *x = sin_reduced(*x);
            }
        } else {
            for x in block.iter_mut() {
                *x = x.sin();
            }
        }
    }
}

const LOG2_E: f32 = core::f32::consts::LOG2_E;
/// ln(2) in two parts; the first has 9 significant bits.
const LN2_A: f32 = 0.693_359_375;
const LN2_B: f32 = -2.121_944_4e-4;
const E2: f32 = 5.000_000_12e-1;
const E3: f32 = 1.666_666_55e-1;
const E4: f32 = 4.166_579_59e-2;
const E5: f32 = 8.333_451_9e-3;
const E6: f32 = 1.398_199_95e-3;
const E7: f32 = 1.987_569_15e-4;
/// The exponential's fast range: `2^k` stays a normal float.
const EXP_MIN: f32 = -87.0;
const EXP_MAX: f32 = 88.0;
/// Below this libm's `expf` is exactly 0.
const EXP_ZERO: f32 = -104.0;

/// `e^x`, `EXP_MIN <= x <= EXP_MAX`.
#[inline(always)]
fn exp_reduced(x: f32) -> f32 {
    let shifted = x * LOG2_E + ROUND_MAGIC;
    let k = shifted - ROUND_MAGIC;
    let r = (x - k * LN2_A) - k * LN2_B;
    let r2 = r * r;
    let p = (((((E7 * r + E6) * r + E5) * r + E4) * r + E3) * r + E2) * r2 + r + 1.0;
    // `k` as an integer from the low bits of `shifted`, then 2^k built
    // from its exponent field.
    let k_int = shifted.to_bits() as i32 - ROUND_MAGIC.to_bits() as i32;
    p * f32::from_bits(((k_int + 127) as u32) << 23)
}

/// `a[i] = e^a[i]` for every element.
#[inline]
pub fn exp_inplace_f32(a: &mut [f32]) {
    #[cfg(feature = "rayon")]
    if a.len() >= PARALLEL_THRESHOLD {
        a.par_chunks_mut(CHUNK_SIZE).for_each(exp_inplace_f32_seq);
        return;
    }
    exp_inplace_f32_seq(a);
}

#[macerator::with_simd]
fn exp_inplace_f32_seq<S: Simd>(a: &mut [f32]) {
    for block in a.chunks_mut(BLOCK) {
        let fast = block.iter().fold(true, |fast, &x| {
            fast & (x <= EXP_MAX) & ((x >= EXP_MIN) | (x < EXP_ZERO))
        });
        if fast {
            for x in block.iter_mut() {
                let e = exp_reduced(x.max(EXP_MIN));
                *x = if *x < EXP_ZERO { 0.0 } else { e };
            }
        } else {
            for x in block.iter_mut() {
                *x = x.exp();
            }
        }
    }
}
