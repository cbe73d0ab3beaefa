//! Plots drawn with plotters into an in-memory bitmap and written as PNG,
//! with a TrueType font read at run time (no system font library).

use std::path::Path;
use std::sync::OnceLock;

use plotters::prelude::*;

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
    datasets::imageio::save_rgb8(path, w, h, &pixels).map_err(|e| e.to_string())
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
