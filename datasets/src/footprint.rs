//! What a capture's frames take in memory once loaded, the size they are
//! trained at by default, and what the machine has: a capture too large
//! is refused before any image is decoded, with the flags that make it fit.
//!
//! A loaded frame holds its colour as 8-bit RGB (3 bytes a pixel) and its
//! depth, where it has any, as 32-bit floats (4 bytes a pixel) or, for a
//! phone's LiDAR depth, half floats (2 bytes) at the training size.
//! Decoding holds a few images at their own size at once (one per
//! thread), and the scene's point cloud keeps one depth pixel in 64 of
//! every frame (and, while the scene box is fitted to it, copies of its
//! positions).

use std::path::Path;

use crate::error::DatasetError;
use crate::options::FrameSelection;

/// A long side above this many pixels is shrunk by default (a phone's
/// 1920 x 1440 is; the photographs of most COLMAP captures are not).
pub const LARGE_LONG_SIDE: u32 = 1280;

/// The long side, in pixels, that images larger than [`LARGE_LONG_SIDE`]
/// are trained at by default.
pub const DEFAULT_LONG_SIDE: u32 = 960;

/// The memory, in bytes, that a capture's frames keep within at their
/// default size: a capture of more frames than fit at
/// [`DEFAULT_LONG_SIDE`] is trained at a smaller size.
pub const FRAME_BUDGET: u64 = 2 << 30;

/// The smallest long side the default size goes down to.
pub const MIN_LONG_SIDE: u32 = 160;

/// Memory of a run besides its frames (the program, the field, a batch, the
/// allocator's slack), in bytes: measured on small captures.
pub const BASE_BYTES: u64 = 600 << 20;

/// The share of the machine's available memory a capture may take when no
/// limit is given.
pub const AVAILABLE_SHARE: f64 = 0.8;

/// Bytes a point of the depth cloud takes while a capture loads.
const POINT_BYTES: u64 = 27 + 96;

/// What a capture's frames need in memory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Frames kept.
    pub frames: usize,
    /// Their size at training, width x height.
    pub size: (u32, u32),
    /// Bytes a pixel of their depth takes (0: no depth).
    pub depth_bytes: u64,
    /// Colour and depth of every frame, in bytes.
    pub frame_bytes: u64,
    /// Decoding and the point cloud, in bytes.
    pub working_bytes: u64,
}

impl Footprint {
    /// The estimate for `frames` frames of own size `own` loaded at `size`
    /// with `depth_bytes` bytes of depth a pixel, decoded `threads` at a
    /// time.
    pub fn new(
        frames: usize,
        own: (u32, u32),
        size: (u32, u32),
        depth_bytes: u64,
        threads: usize,
    ) -> Self {
        let pixels = |(w, h): (u32, u32)| w as u64 * h as u64;
        let per_pixel = 3 + depth_bytes;
        let frame_bytes = frames as u64 * pixels(size) * per_pixel;
        // A decoded image at its own size, 8-bit and as floats while it is
        // resampled, per thread; a point per 64 depth pixels, held with its
        // colour (27 bytes) and in the four copies of its position the
        // scene box is fitted from (96).
        let decoding = threads.max(1) as u64 * pixels(own) * (3 + 12);
        let points = if depth_bytes > 0 {
            frames as u64 * pixels(size) / 64 * POINT_BYTES
        } else {
            0
        };
        Self {
            frames,
            size,
            depth_bytes,
            frame_bytes,
            working_bytes: decoding + points,
        }
    }

    /// The whole estimate, in bytes: frames, working memory and
    /// [`BASE_BYTES`].
    pub fn total(&self) -> u64 {
        self.frame_bytes + self.working_bytes + BASE_BYTES
    }
}

/// `bytes` in GB (10^9): two decimals below 10 GB, one above.
pub fn gigabytes(bytes: u64) -> String {
    let gb = bytes as f64 / 1e9;
    if gb < 10.0 {
        format!("{gb:.2} GB")
    } else {
        format!("{gb:.1} GB")
    }
}

/// The machine's available memory in bytes (`MemAvailable` of
/// `/proc/meminfo`), `None` where it cannot be read.
pub fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The memory limit of a load: the one asked for, else
/// [`AVAILABLE_SHARE`] of the machine's available memory (`None`: no limit
/// known), with how it was decided.
pub fn memory_limit(asked: Option<u64>) -> Option<(u64, String)> {
    match asked {
        Some(b) => Some((b, "--max-memory".into())),
        None => available_memory().map(|a| {
            let limit = (a as f64 * AVAILABLE_SHARE) as u64;
            (
                limit,
                format!(
                    "{:.0}% of the {} this machine has available; --max-memory to change",
                    AVAILABLE_SHARE * 100.0,
                    gigabytes(a)
                ),
            )
        }),
    }
}

/// `own` scaled so that its long side is `long` (aspect kept, each side at
/// least 1).
pub fn with_long_side(own: (u32, u32), long: u32) -> (u32, u32) {
    let (w, h) = own;
    let m = w.max(h).max(1) as f64;
    let scale = |v: u32| ((v as f64 * long as f64 / m).round() as u32).max(1);
    (scale(w), scale(h))
}

/// The largest size with `own`'s aspect and a long side of at most `from`,
/// in steps of 8 pixels down to [`MIN_LONG_SIDE`], that `fits` (the
/// smallest when none does).
fn largest_fitting(own: (u32, u32), from: u32, fits: impl Fn((u32, u32)) -> bool) -> (u32, u32) {
    let mut side = from;
    while side > MIN_LONG_SIDE && !fits(with_long_side(own, side)) {
        side -= 8;
    }
    with_long_side(own, side.max(MIN_LONG_SIDE))
}

/// The size frames of own size `own` are trained at when none is asked
/// for, with why when it is not their own: a long side above
/// [`LARGE_LONG_SIDE`] becomes [`DEFAULT_LONG_SIDE`], and `frames` frames
/// that would take more than [`FRAME_BUDGET`] are made smaller still (down
/// to [`MIN_LONG_SIDE`]).
pub fn default_size(
    own: (u32, u32),
    frames: usize,
    depth_bytes: u64,
) -> ((u32, u32), Option<String>) {
    let long = own.0.max(own.1);
    let mut size = own;
    let mut why = Vec::new();
    if long > LARGE_LONG_SIDE {
        size = with_long_side(own, DEFAULT_LONG_SIDE);
        why.push(format!(
            "images with a long side over {LARGE_LONG_SIDE} px are trained at {DEFAULT_LONG_SIDE}"
        ));
    }
    let bytes = |s| Footprint::new(frames, own, s, depth_bytes, 1).frame_bytes;
    if bytes(size) > FRAME_BUDGET {
        size = largest_fitting(own, size.0.max(size.1), |s| bytes(s) <= FRAME_BUDGET);
        why.push(format!(
            "{frames} frames keep within {} at this size",
            gigabytes(FRAME_BUDGET)
        ));
    }
    let why = (size != own).then(|| why.join("; "));
    (size, why)
}

/// The size a loader loads `frames` frames of own size `own` (with
/// `depth_bytes` bytes of depth a pixel) at: the
/// selection's resolution, else [`default_size`] where the loader
/// resamples (`resamples`), else their own; refused when the estimate
/// ([`Footprint`]) exceeds the memory limit ([`memory_limit`] of the
/// selection's `max_memory`), naming the memory needed and what fits.
/// Returns the size and, when it was chosen here, the line that says so.
pub fn plan_size(
    dir: &Path,
    selection: &FrameSelection,
    frames: usize,
    own: (u32, u32),
    depth_bytes: u64,
    resamples: bool,
) -> Result<((u32, u32), Option<String>), DatasetError> {
    let (size, why) = match selection.resolution {
        Some(r) => (r, None),
        None if resamples => default_size(own, frames, depth_bytes),
        None => (own, None),
    };
    let threads = rayon::current_num_threads();
    let need = Footprint::new(frames, own, size, depth_bytes, threads);
    if let Some((limit, whence)) = memory_limit(selection.max_memory)
        && need.total() > limit
    {
        return Err(DatasetError::invalid(
            dir,
            too_large(&need, own, limit, &whence, threads, resamples),
        ));
    }
    let line = why.map(|why| {
        format!(
            "training resolution {}x{} of the images' {}x{} ({why}; --resolution WxH to \
             change); the {} frames need about {}",
            size.0,
            size.1,
            own.0,
            own.1,
            frames,
            gigabytes(need.total())
        )
    });
    Ok((size, line))
}

/// [`plan_size`] for a loader that loads its `frames` frames at `size`
/// (chosen by its own options), checking only that they fit.
pub fn check_fits(
    dir: &Path,
    selection: &FrameSelection,
    frames: usize,
    size: (u32, u32),
    depth_bytes: u64,
) -> Result<(), DatasetError> {
    let at_size = FrameSelection {
        resolution: Some(size),
        ..*selection
    };
    plan_size(dir, &at_size, frames, size, depth_bytes, false).map(|_| ())
}

/// The refusal of a load that needs more than `limit`: what it needs, and
/// the flags that bring it under.
fn too_large(
    need: &Footprint,
    own: (u32, u32),
    limit: u64,
    whence: &str,
    threads: usize,
    resamples: bool,
) -> String {
    let at = |s| Footprint::new(need.frames, own, s, need.depth_bytes, threads);
    let mut ways = Vec::new();
    if resamples {
        let s = largest_fitting(own, need.size.0.max(need.size.1), |s| {
            at(s).total() <= limit
        });
        let f = at(s);
        if f.total() <= limit {
            ways.push(format!(
                "--resolution {}x{} (about {})",
                s.0,
                s.1,
                gigabytes(f.total())
            ));
        }
    }
    let fixed = Footprint::new(0, own, need.size, need.depth_bytes, threads).total();
    let per_frame = Footprint::new(1, own, need.size, need.depth_bytes, threads).total() - fixed;
    let frames_fit = (limit.saturating_sub(fixed) / per_frame.max(1)) as usize;
    if (1..need.frames).contains(&frames_fit) {
        let stride = need.frames.div_ceil(frames_fit).max(2);
        ways.push(format!("--stride {stride} or --max-frames {frames_fit}"));
    }
    ways.push("--max-memory with more memory".into());
    format!(
        "{} frames at {}x{} would need about {} in memory (colour{} {}, decoding and points {}, \
         the rest {}), more than the {} allowed ({whence}); what fits: {}",
        need.frames,
        need.size.0,
        need.size.1,
        gigabytes(need.total()),
        if need.depth_bytes > 0 {
            " and depth"
        } else {
            ""
        },
        gigabytes(need.frame_bytes),
        gigabytes(need.working_bytes),
        gigabytes(BASE_BYTES),
        gigabytes(limit),
        ways.join("; ")
    )
}

/// Parses a memory size: bytes, or a number with `K`, `M`, `G` or `T`
/// (powers of 1024; `GB`, `GiB` and lower case taken alike), for
/// `--max-memory`.
pub fn parse_memory(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| format!("expected a size such as 8G or 512M, got {s:?}"))?;
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        other => {
            return Err(format!(
                "unknown unit {other:?} in {s:?} (use K, M, G or T)"
            ));
        }
    };
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0) {
        return Err(format!("{s:?} is not a positive size"));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_images_keep_their_size_and_phone_frames_shrink() {
        assert_eq!(default_size((1000, 658), 23, 0), ((1000, 658), None));
        assert_eq!(default_size((504, 378), 20, 0), ((504, 378), None));
        let (size, why) = default_size((1920, 1440), 345, 2);
        assert_eq!(size, (960, 720));
        assert!(why.unwrap().contains("960"));
        let (portrait, _) = default_size((1440, 1920), 10, 2);
        assert_eq!(portrait, (720, 960));
    }

    #[test]
    fn many_frames_are_made_to_fit_the_budget() {
        let (size, why) = default_size((1920, 1440), 2000, 2);
        let bytes = Footprint::new(2000, (1920, 1440), size, 2, 1).frame_bytes;
        assert!(bytes <= FRAME_BUDGET, "{bytes}");
        // Eight pixels more on the long side would not fit.
        let bigger = with_long_side((1920, 1440), size.0 + 8);
        assert!(Footprint::new(2000, (1920, 1440), bigger, 2, 1).frame_bytes > FRAME_BUDGET);
        assert!(why.unwrap().contains("2000 frames"));
    }

    #[test]
    fn the_footprint_adds_up() {
        let f = Footprint::new(10, (200, 100), (100, 50), 4, 2);
        assert_eq!(f.frame_bytes, 10 * 100 * 50 * 7);
        assert_eq!(
            f.working_bytes,
            2 * 200 * 100 * 15 + 10 * 100 * 50 / 64 * 123
        );
        assert_eq!(f.total(), f.frame_bytes + f.working_bytes + BASE_BYTES);
        let half = Footprint::new(10, (200, 100), (100, 50), 2, 2);
        assert_eq!(half.frame_bytes, 10 * 100 * 50 * 5);
        let colour_only = Footprint::new(10, (200, 100), (100, 50), 0, 2);
        assert_eq!(colour_only.frame_bytes, 10 * 100 * 50 * 3);
    }

    #[test]
    fn a_capture_over_the_limit_is_refused_with_what_fits() {
        let selection = FrameSelection {
            resolution: Some((1920, 1440)),
            max_memory: Some(4 << 30),
            ..FrameSelection::default()
        };
        let dir = Path::new("/capture");
        let e = plan_size(dir, &selection, 2000, (1920, 1440), 2, true).unwrap_err();
        let msg = e.to_string();
        for want in [
            "/capture",
            "2000 frames at 1920x1440",
            "--resolution",
            "--stride",
            "--max-frames",
            "--max-memory",
        ] {
            assert!(msg.contains(want), "{want}: {msg}");
        }
        // The resolution it names fits.
        let fitted = msg.split("--resolution ").nth(1).unwrap();
        let (w, rest) = fitted.split_once('x').unwrap();
        let h: String = rest.chars().take_while(char::is_ascii_digit).collect();
        let size = (w.parse().unwrap(), h.parse().unwrap());
        let again = FrameSelection {
            resolution: Some(size),
            ..selection
        };
        assert!(plan_size(dir, &again, 2000, (1920, 1440), 2, true).is_ok());
        // Within the limit: loaded at the size asked for, nothing said.
        let roomy = FrameSelection {
            max_memory: Some(1 << 40),
            ..selection
        };
        assert_eq!(
            plan_size(dir, &roomy, 2000, (1920, 1440), 2, true).unwrap(),
            ((1920, 1440), None)
        );
    }

    #[test]
    fn memory_sizes_parse() {
        assert_eq!(parse_memory("8G"), Ok(8 << 30));
        assert_eq!(parse_memory("512m"), Ok(512 << 20));
        assert_eq!(parse_memory("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_memory("4096"), Ok(4096));
        for bad in ["", "G", "-1G", "8X", "0"] {
            assert!(parse_memory(bad).is_err(), "{bad}");
        }
    }
}
