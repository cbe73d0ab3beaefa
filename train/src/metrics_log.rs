//! `metrics.jsonl`, the log of a run: one [`MetricsEvent`] per line,
//! appended while training (a resumed run appends to the same file) and read
//! back for the training curve, the summary's initial figures and the
//! benchmarks.
//!
//! A line is the event turned into a `serde_json::Value` and printed: its
//! keys come in alphabetical order (the value's map is sorted) and its
//! numbers as `serde_json` prints them, the form every run directory has.
//! JSON has no NaN: a non-finite figure is written as `null`.
//!
//! Reading is lenient where a figure is concerned: one that is missing,
//! `null` or not a number reads as NaN (or `None` where it is optional), so
//! a reader passes over that figure and keeps the rest of the line. A line
//! that is not JSON (one cut short by a kill), lacks its `event` or
//! `iteration`, or names an event unknown here is passed over whole.

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::de::Deserializer;
use serde::ser::Serializer;
use serde::{Deserialize, Serialize};

use crate::accuracy::EvalMetrics;
use crate::error::TrainError;

/// One line of `metrics.jsonl`, told apart by its `"event"` key.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum MetricsEvent {
    /// A training step (every `logging.log_every` iterations and the last).
    Train(TrainLine),
    /// A periodic held-out evaluation on the fixed sample of interior
    /// pixels; iteration 0 is the untrained field.
    Eval(EvalLine),
    /// The evaluation at the end of a session.
    Final(EvalLine),
    /// Novel views joined the training frames.
    NovelViews(NovelViewsLine),
    /// A step skipped for a non-finite loss or gradient.
    Nonfinite(NonfiniteLine),
}

/// A `"train"` line: the batch's losses after the step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrainLine {
    /// Iterations completed.
    pub iteration: usize,
    /// Total loss.
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    pub loss: f64,
    /// Fine colour MSE.
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    pub rgb_mse: f64,
    /// PSNR of the batch's fine colour.
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    pub psnr: f64,
    /// Depth loss.
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    pub depth: f64,
    /// Open-set feature loss.
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    pub open: f64,
    /// Learning rate of the step.
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    pub lr: f64,
    /// Rays per second since the previous training line.
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    pub rays_per_second: f64,
    /// Training wall-clock seconds (all sessions of a resumed run).
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    pub wall_seconds: f64,
    /// With an occupancy grid: what it skipped since the previous line.
    #[serde(flatten)]
    pub grid: Option<GridLine>,
}

/// The occupancy grid's figures of a training line.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GridLine {
    /// Share of the grid's cells occupied.
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    pub occupied_cells: f64,
    /// Share of the drawn rays that were rendered.
    #[serde(deserialize_with = "number_or_nan")]
    pub rays_rendered: f64,
    /// Mean share of a drawn ray's length that was sampled.
    #[serde(deserialize_with = "number_or_nan")]
    pub ray_length_sampled: f64,
}

/// An `"eval"` or `"final"` line. Every figure is suffixed with the pixels
/// it was measured on: `_interior` (inside the border margin, what training
/// draws from) or `_whole` (every pixel of the held-out views).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(from = "EvalKeys", into = "EvalKeys")]
pub struct EvalLine {
    /// Iterations completed.
    pub iteration: usize,
    /// Training wall-clock seconds (all sessions of a resumed run).
    pub wall_seconds: f64,
    /// Figures on interior pixels.
    pub interior: EvalMetrics,
    /// Figures on every pixel, where the views were rendered in full.
    pub whole: Option<EvalMetrics>,
}

/// [`EvalLine`] as its keys are written.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
struct EvalKeys {
    iteration: usize,
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    wall_seconds: f64,
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    psnr_interior: f64,
    #[serde(default, deserialize_with = "number_or_none")]
    depth_mae_interior: Option<f64>,
    #[serde(default, deserialize_with = "number_or_none")]
    feature_cosine_interior: Option<f64>,
    #[serde(default, deserialize_with = "count_or_zero")]
    pixels_interior: u64,
    #[serde(
        default,
        deserialize_with = "number_or_none",
        skip_serializing_if = "Option::is_none"
    )]
    ssim_interior: Option<f64>,
    #[serde(flatten)]
    whole: Option<WholeKeys>,
}

/// The `_whole` keys of an [`EvalLine`], all present or all absent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
struct WholeKeys {
    #[serde(deserialize_with = "number_or_nan")]
    psnr_whole: f64,
    #[serde(default, deserialize_with = "number_or_none")]
    depth_mae_whole: Option<f64>,
    #[serde(default, deserialize_with = "number_or_none")]
    feature_cosine_whole: Option<f64>,
    #[serde(default, deserialize_with = "count_or_zero")]
    pixels_whole: u64,
    #[serde(
        default,
        deserialize_with = "number_or_none",
        skip_serializing_if = "Option::is_none"
    )]
    ssim_whole: Option<f64>,
}

impl From<EvalLine> for EvalKeys {
    fn from(l: EvalLine) -> Self {
        Self {
            iteration: l.iteration,
            wall_seconds: l.wall_seconds,
            psnr_interior: l.interior.psnr,
            depth_mae_interior: l.interior.depth_mae,
            feature_cosine_interior: l.interior.feature_cosine,
            pixels_interior: l.interior.pixels,
            ssim_interior: l.interior.ssim,
            whole: l.whole.map(|w| WholeKeys {
                psnr_whole: w.psnr,
                depth_mae_whole: w.depth_mae,
                feature_cosine_whole: w.feature_cosine,
                pixels_whole: w.pixels,
                ssim_whole: w.ssim,
            }),
        }
    }
}

impl From<EvalKeys> for EvalLine {
    fn from(k: EvalKeys) -> Self {
        Self {
            iteration: k.iteration,
            wall_seconds: k.wall_seconds,
            interior: EvalMetrics {
                psnr: k.psnr_interior,
                depth_mae: k.depth_mae_interior,
                feature_cosine: k.feature_cosine_interior,
                ssim: k.ssim_interior,
                pixels: k.pixels_interior,
            },
            whole: k.whole.map(|w| EvalMetrics {
                psnr: w.psnr_whole,
                depth_mae: w.depth_mae_whole,
                feature_cosine: w.feature_cosine_whole,
                ssim: w.ssim_whole,
                pixels: w.pixels_whole,
            }),
        }
    }
}

/// A `"novel_views"` line.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NovelViewsLine {
    /// Iteration the views were made at.
    pub iteration: usize,
    /// How their cameras were chosen (and, with an oracle, what replaced
    /// the render).
    #[serde(default)]
    pub mode: String,
    /// Views asked for.
    #[serde(default, deserialize_with = "count_or_zero")]
    pub requested: usize,
    /// Views added.
    #[serde(default, deserialize_with = "count_or_zero")]
    pub added: usize,
    /// Seconds spent choosing, rendering and extracting them.
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    pub seconds: f64,
    /// Training wall-clock seconds when they were added.
    #[serde(default = "nan", deserialize_with = "number_or_nan")]
    pub wall_seconds: f64,
}

/// A `"nonfinite"` line. The loss and the gradient's size are written as
/// text (`"NaN"`, `"inf"`), which JSON numbers cannot hold.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NonfiniteLine {
    /// The iteration whose step was skipped.
    pub iteration: usize,
    /// Its loss.
    #[serde(
        default = "nan",
        serialize_with = "as_text",
        deserialize_with = "text_or_nan"
    )]
    pub loss: f64,
    /// Sum of the absolute gradient values.
    #[serde(
        default = "nan",
        serialize_with = "as_text",
        deserialize_with = "text_or_nan"
    )]
    pub grad_l1: f64,
    /// Steps skipped in a row, this one included.
    #[serde(default, deserialize_with = "count_or_zero")]
    pub consecutive: usize,
}

impl MetricsEvent {
    /// The line of the log (without its newline).
    pub fn to_line(&self) -> Result<String, serde_json::Error> {
        serde_json::to_value(self).map(|v| v.to_string())
    }

    /// The event of one line; `None` for a line that is not one (see the
    /// module's documentation).
    pub fn from_line(line: &str) -> Option<Self> {
        serde_json::from_str(line).ok()
    }

    /// Training wall-clock seconds of the event (`None` for a skipped step).
    pub fn wall_seconds(&self) -> Option<f64> {
        match self {
            MetricsEvent::Train(l) => Some(l.wall_seconds),
            MetricsEvent::Eval(l) | MetricsEvent::Final(l) => Some(l.wall_seconds),
            MetricsEvent::NovelViews(l) => Some(l.wall_seconds),
            MetricsEvent::Nonfinite(_) => None,
        }
    }
}

/// The events of the text of a log, in order, without the lines that are
/// not events.
pub fn parse(jsonl: &str) -> Vec<MetricsEvent> {
    jsonl.lines().filter_map(MetricsEvent::from_line).collect()
}

/// The events of the log at `path`.
pub fn read(path: &Path) -> Result<Vec<MetricsEvent>, TrainError> {
    let text = std::fs::read_to_string(path).map_err(|e| TrainError::io(path, e))?;
    Ok(parse(&text))
}

/// The evaluation of the untrained field recorded in the log at `path`
/// (iteration 0); `None` when there is none or the log cannot be read.
pub fn initial_eval(path: &Path) -> Option<EvalMetrics> {
    read(path).ok()?.into_iter().find_map(|e| match e {
        MetricsEvent::Eval(l) if l.iteration == 0 => Some(l.interior),
        _ => None,
    })
}

/// Appends events to `metrics.jsonl`.
#[derive(Debug)]
pub struct MetricsLog {
    path: PathBuf,
    file: std::fs::File,
}

impl MetricsLog {
    /// Opens (creating or appending to) the log at `path`.
    pub fn open(path: &Path) -> Result<Self, TrainError> {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| TrainError::io(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            file,
        })
    }

    /// Writes one event as a line.
    pub fn write(&mut self, event: &MetricsEvent) -> Result<(), TrainError> {
        let mut line = event
            .to_line()
            .map_err(|e| TrainError::json(&self.path, e))?;
        line.push('\n');
        self.file
            .write_all(line.as_bytes())
            .map_err(|e| TrainError::io(&self.path, e))
    }
}

fn nan() -> f64 {
    f64::NAN
}

/// A figure: a number, else NaN.
fn number_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(serde_json::Value::deserialize(d)?
        .as_f64()
        .unwrap_or(f64::NAN))
}

/// A figure written as text (or as a number), else NaN.
fn text_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    let v = serde_json::Value::deserialize(d)?;
    Ok(match &v {
        serde_json::Value::String(s) => s.parse().unwrap_or(f64::NAN),
        _ => v.as_f64().unwrap_or(f64::NAN),
    })
}

/// An optional figure: a number, else `None`.
fn number_or_none<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    Ok(serde_json::Value::deserialize(d)?.as_f64())
}

/// A count: a whole number, else 0.
fn count_or_zero<'de, D, T>(d: D) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    T: TryFrom<u64> + Default,
{
    let v = serde_json::Value::deserialize(d)?;
    Ok(v.as_u64()
        .and_then(|n| T::try_from(n).ok())
        .unwrap_or_default())
}

/// A number written as its text (`f64`'s `Display`, which reads back).
fn as_text<S: Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lines as runs have written them (a run with the occupancy grid and
    /// novel views, one without, one whose steps went non-finite, one whose
    /// final views were measured with SSIM).
    const LINES: [&str; 8] = [
        r#"{"depth_mae_interior":1.3088842583820224,"event":"eval","feature_cosine_interior":0.026067644235930797,"iteration":0,"pixels_interior":1024,"psnr_interior":11.814963046118843,"wall_seconds":0.0}"#,
        r#"{"depth":0.2795112431049347,"event":"train","iteration":25,"loss":0.5102336406707764,"lr":0.0014254075868100975,"open":0.44456246495246887,"psnr":14.979057145000725,"rays_per_second":1528.9983051543545,"rgb_mse":0.031775638461112976,"wall_seconds":5.051209602}"#,
        r#"{"depth":0.27766841650009155,"event":"train","iteration":25,"loss":0.47789937257766724,"lr":0.0017944818331994334,"occupied_cells":1.0,"open":0.41272127628326416,"psnr":15.015101234715832,"ray_length_sampled":1.0,"rays_per_second":1241.6744575676016,"rays_rendered":1.0,"rgb_mse":0.03151300922036171,"wall_seconds":6.261850738}"#,
        r#"{"added":2,"event":"novel_views","iteration":40,"mode":"guided","requested":2,"seconds":1.183546406,"wall_seconds":9.928305697999999}"#,
        r#"{"depth_mae_interior":1.4597540040206218,"depth_mae_whole":1.4327181395710495,"event":"final","feature_cosine_interior":0.9101479023412206,"feature_cosine_whole":0.9107054511141833,"iteration":50,"pixels_interior":13800,"pixels_whole":15552,"psnr_interior":15.226301197058751,"psnr_whole":15.223258946736307,"wall_seconds":18.562902343}"#,
        r#"{"consecutive":1,"event":"nonfinite","grad_l1":"NaN","iteration":1,"loss":"NaN"}"#,
        r#"{"depth_mae_interior":null,"depth_mae_whole":null,"event":"final","feature_cosine_interior":null,"feature_cosine_whole":null,"iteration":20,"pixels_interior":13800,"pixels_whole":15552,"psnr_interior":200.0,"psnr_whole":200.0,"wall_seconds":10.971060369}"#,
        r#"{"depth_mae_interior":0.25,"depth_mae_whole":0.5,"event":"final","feature_cosine_interior":null,"feature_cosine_whole":null,"iteration":30,"pixels_interior":13800,"pixels_whole":15552,"psnr_interior":21.5,"psnr_whole":20.25,"ssim_interior":0.71875,"ssim_whole":0.6875,"wall_seconds":12.5}"#,
    ];

    #[test]
    fn lines_read_back_and_are_written_byte_for_byte_as_before() {
        for line in LINES {
            let event = MetricsEvent::from_line(line).unwrap_or_else(|| panic!("{line}"));
            assert_eq!(event.to_line().unwrap(), line);
        }
        let grid = MetricsEvent::from_line(LINES[2]).unwrap();
        let MetricsEvent::Train(t) = grid else {
            panic!("{grid:?}");
        };
        assert_eq!(t.grid.map(|g| g.rays_rendered), Some(1.0));
        let MetricsEvent::Train(t) = MetricsEvent::from_line(LINES[1]).unwrap() else {
            panic!();
        };
        assert!(t.grid.is_none());
        let MetricsEvent::Final(f) = MetricsEvent::from_line(LINES[4]).unwrap() else {
            panic!();
        };
        assert_eq!(f.whole.map(|w| w.pixels), Some(15552));
        assert!(f.interior.ssim.is_none() && f.whole.is_some_and(|w| w.ssim.is_none()));
        let MetricsEvent::Final(f) = MetricsEvent::from_line(LINES[7]).unwrap() else {
            panic!();
        };
        assert_eq!(f.interior.ssim, Some(0.71875));
        assert_eq!(f.whole.and_then(|w| w.ssim), Some(0.6875));
        let MetricsEvent::Eval(e) = MetricsEvent::from_line(LINES[0]).unwrap() else {
            panic!();
        };
        assert!(e.whole.is_none() && e.interior.pixels == 1024);
    }

    #[test]
    fn non_finite_figures_are_written_as_null_or_text_and_read_as_nan() {
        let step = MetricsEvent::Nonfinite(NonfiniteLine {
            iteration: 3,
            loss: f64::INFINITY,
            grad_l1: f64::NAN,
            consecutive: 2,
        });
        let line = step.to_line().unwrap();
        assert_eq!(
            line,
            r#"{"consecutive":2,"event":"nonfinite","grad_l1":"NaN","iteration":3,"loss":"inf"}"#
        );
        let MetricsEvent::Nonfinite(back) = MetricsEvent::from_line(&line).unwrap() else {
            panic!();
        };
        assert!(back.loss == f64::INFINITY && back.grad_l1.is_nan());
        let eval = MetricsEvent::Eval(EvalLine {
            iteration: 0,
            wall_seconds: 0.0,
            interior: EvalMetrics {
                psnr: f64::NAN,
                depth_mae: Some(f64::NAN),
                feature_cosine: None,
                ssim: None,
                pixels: 4,
            },
            whole: None,
        });
        let line = eval.to_line().unwrap();
        assert!(line.contains(r#""psnr_interior":null"#), "{line}");
        let MetricsEvent::Eval(back) = MetricsEvent::from_line(&line).unwrap() else {
            panic!();
        };
        assert!(back.interior.psnr.is_nan() && back.interior.depth_mae.is_none());
    }

    #[test]
    fn cut_and_unknown_lines_are_passed_over() {
        let text = [
            LINES[0],
            r#"{"event":"train","iteration":75,"loss":0.1"#,
            r#"{"event":"something_new","iteration":3}"#,
            r#"{"event":"eval","psnr_interior":3.0}"#,
            LINES[3],
        ]
        .join("\n");
        let events = parse(&text);
        assert_eq!(events.len(), 2);
        assert!(matches!(events[1], MetricsEvent::NovelViews(_)));
    }

    #[test]
    fn the_initial_evaluation_is_found_in_the_log() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("metrics.jsonl");
        assert_eq!(initial_eval(&path), None);
        let mut log = MetricsLog::open(&path).unwrap();
        for line in [LINES[1], LINES[0]] {
            log.write(&MetricsEvent::from_line(line).unwrap()).unwrap();
        }
        let m = initial_eval(&path).unwrap();
        assert_eq!((m.psnr, m.pixels), (11.814963046118843, 1024));
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            format!("{}\n{}\n", LINES[1], LINES[0])
        );
    }
}
