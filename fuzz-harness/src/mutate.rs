//! Byte-level mutations of a seed file, chosen by `arbitrary` from a
//! deterministic stream of random bytes.
//!
//! Execution `i` of a target is a pure function of the target's seeds and
//! `i` (see [`input_for`]): no state carries from one execution to the
//! next, so the supervisor can rebuild the input of a failing execution
//! from its index alone, even after the worker died.

use arbitrary::{Arbitrary, Unstructured};
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Largest input a mutation may produce (bytes).
const MAX_INPUT: usize = 4 << 20;
/// Positions fall in the first this-many bytes half of the time: headers
/// (counts, shapes, offsets) are where most parsing decisions are made.
const HEAD: usize = 512;

/// Integers that sit on type and sign boundaries, written little-endian
/// into binary formats.
const INTERESTING: [u64; 16] = [
    0,
    1,
    2,
    0x7f,
    0x80,
    0xff,
    0x7fff,
    0xffff,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
    1 << 32,
    1 << 40,
    0x7fff_ffff_ffff_ffff,
    0x8000_0000_0000_0000,
    u64::MAX,
];

/// Numbers written in place of a number of a text format.
const NUMBERS: [&str; 20] = [
    "0",
    "-1",
    "-0",
    "1e308",
    "1e309",
    "-1e309",
    "1e-320",
    "NaN",
    "inf",
    "65536",
    "2147483648",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "18446744073709551615",
    "18446744073709551616",
    "999999999999",
    "0.5",
    "3",
    "100000000",
];

/// Tokens every target gets (JSON and text structure, odd characters).
pub const COMMON_TOKENS: [&str; 18] = [
    "{",
    "}",
    "[",
    "]",
    ",",
    ":",
    "\"",
    "null",
    "true",
    "\n",
    " ",
    "\t",
    "\u{e9}",
    "\u{1F600}",
    "\\u0000",
    "\\ud800",
    "\r\n",
    "\0",
];

/// One change to the input; positions are reduced modulo the input's
/// length when applied.
#[derive(Debug, Clone, PartialEq)]
pub enum Mutation {
    /// Flips one bit.
    FlipBit { at: Pos, bit: u8 },
    /// Sets one byte.
    SetByte { at: Pos, value: u8 },
    /// Writes an interesting integer of 1, 2, 4 or 8 bytes.
    Interesting { at: Pos, width: u8, value: u64 },
    /// Adds a small signed amount to a byte.
    AddByte { at: Pos, delta: i8 },
    /// Removes up to `len` bytes.
    Delete { at: Pos, len: u16 },
    /// Copies up to `len` bytes from one place to another (inserted).
    Duplicate { from: Pos, to: Pos, len: u16 },
    /// Inserts random bytes.
    Insert { at: Pos, bytes: Vec<u8> },
    /// Cuts the input at a position.
    Truncate { at: Pos },
    /// Inserts (or overwrites with) a token of the target's dictionary.
    Token {
        at: Pos,
        index: u16,
        overwrite: bool,
    },
    /// Replaces the `nth` decimal number of the text with a boundary value.
    Number { nth: u16, index: u8 },
    /// Keeps the start of the input and continues with the end of another
    /// seed.
    Splice { seed: u16, at: Pos, from: Pos },
}

/// A position: in the first `HEAD` bytes or anywhere.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pos {
    head: bool,
    raw: u32,
}

impl Pos {
    fn resolve(self, len: usize) -> usize {
        let span = if self.head { len.min(HEAD) } else { len };
        if span == 0 {
            0
        } else {
            self.raw as usize % span
        }
    }
}

impl<'a> Arbitrary<'a> for Pos {
    fn arbitrary(u: &mut Unstructured<'a>) -> arbitrary::Result<Self> {
        Ok(Self {
            head: u.arbitrary()?,
            raw: u.arbitrary()?,
        })
    }
}

impl<'a> Arbitrary<'a> for Mutation {
    fn arbitrary(u: &mut Unstructured<'a>) -> arbitrary::Result<Self> {
        Ok(match u.int_in_range(0..=10u8)? {
            0 => Self::FlipBit {
                at: u.arbitrary()?,
                bit: u.int_in_range(0..=7)?,
            },
            1 => Self::SetByte {
                at: u.arbitrary()?,
                value: u.arbitrary()?,
            },
            2 => Self::Interesting {
                at: u.arbitrary()?,
                width: *u.choose(&[1, 2, 4, 8])?,
                value: *u.choose(&INTERESTING)?,
            },
            3 => Self::AddByte {
                at: u.arbitrary()?,
                delta: u.int_in_range(-16..=16)?,
            },
            4 => Self::Delete {
                at: u.arbitrary()?,
                len: u.int_in_range(1..=64)?,
            },
            5 => Self::Duplicate {
                from: u.arbitrary()?,
                to: u.arbitrary()?,
                len: u.int_in_range(1..=256)?,
            },
            6 => {
                let n = u.int_in_range(1..=16)?;
                Self::Insert {
                    at: u.arbitrary()?,
                    bytes: (0..n).map(|_| u.arbitrary()).collect::<Result<_, _>>()?,
                }
            }
            7 => Self::Truncate { at: u.arbitrary()? },
            8 => Self::Token {
                at: u.arbitrary()?,
                index: u.arbitrary()?,
                overwrite: u.arbitrary()?,
            },
            9 => Self::Number {
                nth: u.int_in_range(0..=63)?,
                index: u.arbitrary()?,
            },
            _ => Self::Splice {
                seed: u.arbitrary()?,
                at: u.arbitrary()?,
                from: u.arbitrary()?,
            },
        })
    }
}

/// Where the decimal numbers of `data` are (start, end).
fn numbers(data: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if data[i].is_ascii_digit() {
            let start = if i > 0 && data[i - 1] == b'-' {
                i - 1
            } else {
                i
            };
            let mut end = i;
            while end < data.len() && (data[end].is_ascii_digit() || b".eE+-".contains(&data[end]))
            {
                end += 1;
            }
            out.push((start, end));
            i = end;
        } else {
            i += 1;
        }
    }
    out
}

impl Mutation {
    /// Applies the mutation to `data`; `seeds` and `tokens` feed splicing and
    /// dictionary insertion.
    pub fn apply(&self, data: &mut Vec<u8>, seeds: &[Vec<u8>], tokens: &[&str]) {
        let len = data.len();
        match self {
            Self::FlipBit { at, bit } if len > 0 => data[at.resolve(len)] ^= 1 << bit,
            Self::SetByte { at, value } if len > 0 => data[at.resolve(len)] = *value,
            Self::Interesting { at, width, value } if len > 0 => {
                let at = at.resolve(len);
                let bytes = value.to_le_bytes();
                let n = (*width as usize).min(len - at);
                data[at..at + n].copy_from_slice(&bytes[..n]);
            }
            Self::AddByte { at, delta } if len > 0 => {
                let b = &mut data[at.resolve(len)];
                *b = b.wrapping_add_signed(*delta);
            }
            Self::Delete { at, len: n } if len > 0 => {
                let at = at.resolve(len);
                let end = (at + *n as usize).min(len);
                data.drain(at..end);
            }
            Self::Duplicate { from, to, len: n } if len > 0 => {
                let from = from.resolve(len);
                let end = (from + *n as usize).min(len);
                let chunk = data[from..end].to_vec();
                let to = to.resolve(len + 1);
                data.splice(to..to, chunk);
            }
            Self::Insert { at, bytes } => {
                let at = at.resolve(len + 1);
                data.splice(at..at, bytes.iter().copied());
            }
            Self::Truncate { at } => data.truncate(at.resolve(len)),
            Self::Token {
                at,
                index,
                overwrite,
            } if !tokens.is_empty() => {
                let token = tokens[*index as usize % tokens.len()].as_bytes();
                let at = at.resolve(len + 1);
                let end = if *overwrite {
                    (at + token.len()).min(len)
                } else {
                    at
                };
                data.splice(at..end, token.iter().copied());
            }
            Self::Number { nth, index } => {
                let found = numbers(data);
                if let Some(&(start, end)) = found.get(*nth as usize % found.len().max(1)) {
                    let n = NUMBERS[*index as usize % NUMBERS.len()].as_bytes();
                    data.splice(start..end, n.iter().copied());
                }
            }
            Self::Splice { seed, at, from } if !seeds.is_empty() => {
                let other = &seeds[*seed as usize % seeds.len()];
                data.truncate(at.resolve(len + 1));
                data.extend_from_slice(&other[from.resolve(other.len() + 1)..]);
            }
            _ => {}
        }
        data.truncate(MAX_INPUT);
    }
}

/// The random stream of execution `index` of the target named `target`.
fn rng_for(target: &str, index: u64) -> ChaCha8Rng {
    // FNV-1a of the name, so that targets sharing seeds still differ.
    let name = target.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
    });
    let mut rng = ChaCha8Rng::seed_from_u64(name);
    rng.set_stream(index);
    rng
}

/// The input of execution `index`: the seeds themselves first (each must
/// pass as it is), then a seed (round robin) with 1, 2, 4 or 8 mutations.
pub fn input_for(target: &str, seeds: &[Vec<u8>], tokens: &[&str], index: u64) -> Vec<u8> {
    if seeds.is_empty() {
        return Vec::new();
    }
    let n = seeds.len() as u64;
    let mut data = seeds[(index % n) as usize].clone();
    if index < n {
        return data;
    }
    let mut entropy = [0u8; 512];
    rng_for(target, index).fill_bytes(&mut entropy);
    let mut u = Unstructured::new(&entropy);
    let count = 1usize << u.int_in_range(0..=3u8).unwrap_or(0);
    for _ in 0..count {
        match Mutation::arbitrary(&mut u) {
            Ok(m) => m.apply(&mut data, seeds, tokens),
            Err(_) => break,
        }
    }
    data
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_are_a_function_of_the_index() {
        let seeds = vec![b"{\"a\": 12, \"b\": [1, 2]}".to_vec(), vec![0u8; 40]];
        for i in 0..200 {
            let a = input_for("t", &seeds, &COMMON_TOKENS, i);
            assert_eq!(a, input_for("t", &seeds, &COMMON_TOKENS, i));
        }
        assert_eq!(input_for("t", &seeds, &[], 1), seeds[1]);
        let changed = (2..200)
            .filter(|&i| input_for("t", &seeds, &[], i) != seeds[(i % 2) as usize])
            .count();
        assert!(changed > 150, "{changed}");
    }

    #[test]
    fn every_mutation_keeps_within_bounds_of_small_inputs() {
        for len in 0..4 {
            for i in 0..2000 {
                let seeds = vec![vec![7u8; len]];
                let _ = input_for("bounds", &seeds, &COMMON_TOKENS, i);
            }
        }
    }
}
