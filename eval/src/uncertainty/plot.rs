//! The uncertainty-against-error scatter plot.

use std::path::Path;
use std::sync::OnceLock;

use plotters::prelude::*;

use super::UncertaintyMap;
use crate::error::EvalError;

/// Most points drawn (an even subsample beyond that keeps the file small).
const MAX_DOTS: usize = 20_000;

/// Draws `log det` (x) against the feature error (y) of the points seen at
/// least twice with a finite error, with Pearson's r in the caption.
pub fn scatter(
    path: &Path,
    map: &UncertaintyMap,
    errors: &[f64],
    r: Option<f64>,
) -> Result<(), EvalError> {
    let pts: Vec<(f64, f64)> = (0..map.counts.len())
        .filter(|&i| map.counts[i] >= 2 && errors[i].is_finite())
        .map(|i| (map.log_det[i], errors[i]))
        .collect();
    let step = pts.len().div_ceil(MAX_DOTS).max(1);
    let dots: Vec<(f64, f64)> = pts.iter().step_by(step).copied().collect();
    let (x0, x1) = range(dots.iter().map(|d| d.0));
    let (y0, y1) = range(dots.iter().map(|d| d.1));
    let (w, h) = (800u32, 600u32);
    draw_png(path, w, h, |root| {
        let caption = match r {
            Some(r) => format!(
                "uncertainty vs feature error (Pearson r = {r:.3}, {} points)",
                pts.len()
            ),
            None => format!("uncertainty vs feature error ({} points)", pts.len()),
        };
        let mut chart = ChartBuilder::on(root)
            .caption(caption, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc(format!("log det(Sigma + eps I), k = {}", map.k))
            .y_desc("1 - cos(mean feature, class embedding)")
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(
                dots.iter()
                    .map(|&(x, y)| Circle::new((x, y), 2, BLUE.mix(0.25).filled())),
            )
            .map_err(|e| e.to_string())?;
        Ok(())
    })
    .map_err(EvalError::Invalid)
}

/// The drawing area of an in-memory RGB bitmap.
pub type Canvas<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// Draws a `w x h` picture with `draw` on a white canvas (after checking
/// that a font is available) and writes it to `path` as PNG; errors name
/// the file.
pub fn draw_png(
    path: &Path,
    w: u32,
    h: u32,
    draw: impl FnOnce(&Canvas<'_>) -> Result<(), String>,
) -> Result<(), String> {
    let err = |e: String| format!("drawing {}: {e}", path.display());
    ensure_font().map_err(err)?;
    let mut pixels = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        draw(&root).map_err(err)?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    save_png(path, w, h, pixels).map_err(err)
}

/// Saves a `w x h` RGB buffer drawn by plotters' bitmap backend as a PNG.
pub fn save_png(path: &Path, w: u32, h: u32, pixels: Vec<u8>) -> Result<(), String> {
    image::RgbImage::from_raw(w, h, pixels)
        .ok_or_else(|| "the image buffer has the wrong size".to_string())?
        .save(path)
        .map_err(|e| e.to_string())
}

/// TrueType fonts looked for, in order, for the plots' text (plots are
/// drawn without a system font library).
const FONT_PATHS: [&str; 4] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/Library/Fonts/Arial.ttf",
];

/// Registers the first font found as "sans-serif" (once per process).
pub fn ensure_font() -> Result<(), String> {
    static FONT: OnceLock<Result<(), String>> = OnceLock::new();
    FONT.get_or_init(|| {
        let bytes = std::env::var_os("OPENNERF_PLOT_FONT")
            .map(std::path::PathBuf::from)
            .into_iter()
            .chain(FONT_PATHS.iter().map(std::path::PathBuf::from))
            .find_map(|p| std::fs::read(p).ok())
            .ok_or_else(|| {
                format!(
                    "no TrueType font for the plot's text (set OPENNERF_PLOT_FONT, or install one of {FONT_PATHS:?})"
                )
            })?;
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
            .map_err(|_| "the plot font could not be read".to_string())
    })
    .clone()
}

/// A padded `[min, max]` of finite values (`[0, 1]` when there are none).
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-6);
    (lo - pad, hi + pad)
}
