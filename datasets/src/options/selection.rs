//! [`FrameSelection`]: which frames of a capture every loader keeps, and at
//! what size; [`Resolution`] and [`parse_count`] for the command lines that
//! set them.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::detect::Format;
use crate::error::DatasetError;

/// Which frames a loader keeps and the size it loads them at, shared by
/// every format on disk. Serialised flattened into each format's options
/// (the keys `stride`, `max_frames`, `resolution`, `sharpest_of`), as they
/// were before the formats shared it; the memory limit is the machine's,
/// not the scene's, and is not saved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct FrameSelection {
    /// Keep every `stride`-th frame (at least 1), in the loader's order
    /// (Replica and phone captures: capture order; ScanNet: the numbered
    /// frames with valid poses; COLMAP and LLFF: image name order; Blender:
    /// the transforms file's order).
    pub stride: usize,
    /// Keep at most this many frames (after the stride).
    pub max_frames: Option<usize>,
    /// Resample the images to `(width, height)`, intrinsics scaled; a
    /// format whose loader cannot resample refuses it
    /// ([`DatasetError::Unsupported`]).
    pub resolution: Option<(u32, u32)>,
    /// Keep the sharpest frame (largest variance of the Laplacian of its
    /// luminance, [`crate::sharpness`]) of each window of this many
    /// consecutive frames, instead of every `stride`-th.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sharpest_of: Option<usize>,
    /// The most memory the loaded frames may need, in bytes (`None`: the
    /// machine's, [`crate::footprint::memory_limit`]). A capture that
    /// would need more is refused before its images are decoded.
    #[serde(skip)]
    pub max_memory: Option<u64>,
}

impl Default for FrameSelection {
    fn default() -> Self {
        Self {
            stride: 1,
            max_frames: None,
            resolution: None,
            sharpest_of: None,
            max_memory: None,
        }
    }
}

impl FrameSelection {
    /// Checks the selection before a loader reads anything: the stride is
    /// at least 1, a resolution has no zero side. Errors name `dir`.
    pub fn check(&self, dir: &Path) -> Result<(), DatasetError> {
        if self.stride == 0 {
            return Err(DatasetError::invalid(dir, "stride must be at least 1"));
        }
        if let Some((w, h)) = self.resolution
            && (w == 0 || h == 0)
        {
            return Err(DatasetError::invalid(dir, "resolution is zero"));
        }
        match self.sharpest_of {
            Some(0) => Err(DatasetError::invalid(dir, "sharpest-of must be at least 1")),
            Some(_) if self.stride > 1 => Err(DatasetError::invalid(
                dir,
                "stride and sharpest-of both choose the frames kept: give one of them",
            )),
            _ => Ok(()),
        }
    }

    /// [`Self::check`] for a `format` whose loader cannot resample: a
    /// resolution is refused, naming the option and what to use instead.
    pub fn check_without_resampling(
        &self,
        dir: &Path,
        format: Format,
        instead: &str,
    ) -> Result<(), DatasetError> {
        self.check(dir)?;
        match self.resolution {
            Some(_) => Err(DatasetError::Unsupported {
                path: dir.to_path_buf(),
                format: format.name(),
                option: "resolution",
                instead: instead.into(),
            }),
            None => Ok(()),
        }
    }

    /// The frames kept of `frames` (in the loader's order): every
    /// `stride`-th, then at most `max_frames`. A stride of 0 (refused by
    /// [`Self::check`]) keeps every frame.
    pub fn select<T>(&self, frames: impl IntoIterator<Item = T>) -> Vec<T> {
        frames
            .into_iter()
            .step_by(self.stride.max(1))
            .take(self.max_frames.unwrap_or(usize::MAX))
            .collect()
    }

    /// The frames kept of `frames` when they may be chosen by sharpness:
    /// with [`Self::sharpest_of`], the one of each window of that many
    /// consecutive frames whose `score` is highest (the first on a tie;
    /// scores are computed in parallel, with a progress bar), then at most
    /// `max_frames`; otherwise [`Self::select`]. `score` errors are
    /// returned.
    pub fn select_sharpest<T: Send + Sync>(
        &self,
        frames: Vec<T>,
        score: impl Fn(&T) -> Result<f64, DatasetError> + Sync,
    ) -> Result<Vec<T>, DatasetError> {
        let Some(k) = self.sharpest_of.filter(|&k| k > 1) else {
            return Ok(self.select(frames));
        };
        let scores = crate::progress::par_map(&frames, "scoring sharpness", score)?;
        let best: Vec<usize> = scores
            .chunks(k)
            .enumerate()
            .map(|(w, chunk)| {
                let mut b = 0;
                for (i, s) in chunk.iter().enumerate() {
                    if *s > chunk[b] {
                        b = i;
                    }
                }
                w * k + b
            })
            .take(self.max_frames.unwrap_or(usize::MAX))
            .collect();
        let mut keep = best.into_iter().peekable();
        Ok(frames
            .into_iter()
            .enumerate()
            .filter_map(|(i, f)| {
                (keep.peek() == Some(&i)).then(|| {
                    keep.next();
                    f
                })
            })
            .collect())
    }

    /// The size images are loaded at: the resolution asked for, else
    /// `own`, the images' own size.
    pub fn size(&self, own: (u32, u32)) -> (u32, u32) {
        self.resolution.unwrap_or(own)
    }
}

/// An image size `WxH`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Resolution {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl std::str::FromStr for Resolution {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (w, h) = s
            .split_once(['x', 'X'])
            .ok_or_else(|| format!("expected WxH (e.g. 320x180), got {s:?}"))?;
        let parse = |v: &str| {
            v.trim()
                .parse::<u32>()
                .ok()
                .filter(|&n| n > 0)
                .ok_or_else(|| format!("expected a positive integer in {s:?}, got {v:?}"))
        };
        Ok(Self {
            width: parse(w)?,
            height: parse(h)?,
        })
    }
}

/// Parses a count of at least 1 (a stride, a number of frames), for the
/// command lines that set a [`FrameSelection`]: 0, negative numbers and
/// words are refused with what was expected.
pub fn parse_count(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(0) => Err("must be at least 1".into()),
        Ok(n) => Ok(n),
        Err(_) => Err(format!("expected a whole number of at least 1, got {s:?}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn select_strides_then_caps_in_order() {
        let pick = |stride, max_frames| {
            FrameSelection {
                stride,
                max_frames,
                resolution: None,
                ..FrameSelection::default()
            }
            .select(0..10)
        };
        assert_eq!(pick(1, None), (0..10).collect::<Vec<_>>());
        assert_eq!(pick(3, None), vec![0, 3, 6, 9]);
        assert_eq!(pick(2, Some(3)), vec![0, 2, 4]);
        assert_eq!(pick(4, Some(9)), vec![0, 4, 8]);
        assert_eq!(pick(1, Some(0)), Vec::<i32>::new());
    }

    #[test]
    fn sharpest_of_keeps_the_best_of_each_window() {
        let scores = [1.0, 5.0, 2.0, 9.0, 0.0, 9.0, 4.0];
        let pick = |k, max_frames| {
            FrameSelection {
                sharpest_of: Some(k),
                max_frames,
                ..FrameSelection::default()
            }
            .select_sharpest((0..7).collect(), |&i: &usize| Ok(scores[i]))
            .unwrap()
        };
        // Windows 0..3, 3..6 (a tie: the first) and 6..7.
        assert_eq!(pick(3, None), vec![1, 3, 6]);
        assert_eq!(pick(3, Some(2)), vec![1, 3]);
        assert_eq!(pick(7, None), vec![3]);
        // A window of one keeps every frame, without scoring any.
        let all = FrameSelection {
            sharpest_of: Some(1),
            ..FrameSelection::default()
        }
        .select_sharpest((0..4).collect(), |_: &usize| -> Result<f64, DatasetError> {
            panic!("scored")
        })
        .unwrap();
        assert_eq!(all, vec![0, 1, 2, 3]);
        let failing = FrameSelection {
            sharpest_of: Some(2),
            ..FrameSelection::default()
        }
        .select_sharpest((0..4).collect(), |&i: &usize| {
            if i == 2 {
                Err(DatasetError::invalid("/scene/2.jpg", "cannot decode image"))
            } else {
                Ok(1.0)
            }
        });
        assert!(failing.unwrap_err().to_string().contains("2.jpg"));
        let dir = Path::new("/scene");
        let zero = FrameSelection {
            sharpest_of: Some(0),
            ..FrameSelection::default()
        };
        assert!(
            zero.check(dir)
                .unwrap_err()
                .to_string()
                .contains("sharpest-of")
        );
        let both = FrameSelection {
            sharpest_of: Some(3),
            stride: 2,
            ..FrameSelection::default()
        };
        assert!(both.check(dir).unwrap_err().to_string().contains("stride"));
    }

    #[test]
    fn check_names_the_bad_option() {
        let dir = Path::new("/scene");
        let zero = FrameSelection {
            stride: 0,
            ..FrameSelection::default()
        };
        assert!(zero.check(dir).unwrap_err().to_string().contains("stride"));
        let flat = FrameSelection {
            resolution: Some((0, 4)),
            ..FrameSelection::default()
        };
        assert!(
            flat.check(dir)
                .unwrap_err()
                .to_string()
                .contains("resolution")
        );
        let sized = FrameSelection {
            resolution: Some((8, 4)),
            ..FrameSelection::default()
        };
        assert!(sized.check(dir).is_ok());
        let e = sized
            .check_without_resampling(dir, Format::Llff, "an images_F folder")
            .unwrap_err();
        assert!(matches!(
            e,
            DatasetError::Unsupported {
                format: "llff",
                option: "resolution",
                ..
            }
        ));
        let msg = e.to_string();
        assert!(
            msg.contains("/scene") && msg.contains("llff") && msg.contains("resolution"),
            "{msg}"
        );
        assert_eq!(sized.size((2, 1)), (8, 4));
        assert_eq!(FrameSelection::default().size((2, 1)), (2, 1));
    }

    #[test]
    fn counts_are_at_least_one() {
        assert_eq!(parse_count("3"), Ok(3));
        for bad in ["0", "-1", "two", "", "1.5"] {
            assert!(parse_count(bad).is_err(), "{bad}");
        }
        assert!(parse_count("0").unwrap_err().contains("at least 1"));
    }
}
