//! The held-out views in full at the end of a session: each rendered (with
//! [`field_ops::render`]) and written as pictures, measured over its
//! interior pixels and over every pixel (PSNR, depth error, feature cosine,
//! SSIM), shown beside its photograph in a strip, and all strips on one
//! contact sheet.

use std::path::Path;

use datasets::Scene;
use field_ops::depth_image::DepthQuantity;
use field_ops::images::ViewImages;
use field_ops::render::{RenderedView, ViewSettings, render_view};
use field_ops::ssim::ssim_map;
use field_ops::strips::Strips;
use model::OpenNerf;
use serde::{Deserialize, Serialize};

use crate::accuracy::{EvalAccumulator, EvalMetrics};
use crate::error::TrainError;
use crate::evaluate::lift_features;

/// The contact sheet of every held-out strip, in the renders directory.
pub const CONTACT_SHEET: &str = "heldout.png";

/// Metrics of whole held-out views, over the interior pixels (those the
/// training sampler draws from: the border margin left out) and over every
/// pixel; masked-out pixels are left out of both.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewMetrics {
    /// Pixels at least the (scaled) border margin from the image border.
    pub interior: EvalMetrics,
    /// All pixels, the never-supervised border included.
    pub whole: EvalMetrics,
    /// The figures of each view, in the order rendered.
    pub views: Vec<ViewFigures>,
}

/// The figures of one held-out view, so that a view that fails shows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewFigures {
    /// The frame's name (its pictures are `renders/{name}_*.png`).
    pub name: String,
    /// The frame's index in the scene.
    pub frame: usize,
    /// PSNR over the interior pixels, dB.
    pub psnr_interior: f64,
    /// PSNR over every pixel, dB.
    pub psnr_whole: f64,
    /// SSIM averaged over the interior window centres (`None`: a view
    /// smaller than the SSIM window).
    pub ssim_interior: Option<f64>,
    /// SSIM averaged over every window centre.
    pub ssim_whole: Option<f64>,
}

/// Renders every view of `frames` in full, writes its pictures and its
/// strip (`{name}_strip.png`: photograph, render, error, depth) into
/// `renders_dir` with the contact sheet [`CONTACT_SHEET`], and returns the
/// metrics over their interior pixels (border margin `margin`, scaled like
/// the sampler's), over all their pixels and per view.
pub fn evaluate_views(
    model: &OpenNerf,
    scene: &Scene,
    frames: &[usize],
    margin: u32,
    chunk: usize,
    renders_dir: &Path,
) -> Result<ViewMetrics, TrainError> {
    let mut interior = EvalAccumulator::default();
    let mut whole = EvalAccumulator::default();
    let settings =
        ViewSettings::new(scene.background, chunk).with_features(scene.features.is_some());
    let quantity = DepthQuantity::of(model);
    let mut views = Vec::new();
    let mut strips = Strips::default();
    for &f in frames {
        let frame = &scene.frames[f];
        let mut view = render_view(model, &frame.camera, &scene.scene_box, &settings)
            .expect("never cancelled without an observer");
        if scene.features.is_none() {
            // The head of a scene without features is a stub: no feature image.
            view.feature.clear();
            view.feature_dim = 0;
        }
        let images = ViewImages::of(&view, quantity);
        images.save(renders_dir, &frame.name)?;
        let [one_interior, one_whole] =
            measure_view(scene, f, &view, margin, [&mut interior, &mut whole]);
        views.push(ViewFigures {
            name: frame.name.clone(),
            frame: f,
            psnr_interior: one_interior.psnr,
            psnr_whole: one_whole.psnr,
            ssim_interior: one_interior.ssim,
            ssim_whole: one_whole.ssim,
        });
        strips.add(&frame.rgb, &view, &images.depth, renders_dir, &frame.name)?;
    }
    strips.write_sheet(&renders_dir.join(CONTACT_SHEET))?;
    Ok(ViewMetrics {
        interior: interior.finish(),
        whole: whole.finish(),
        views,
    })
}

/// Frame `f`'s rendered `view` against its targets, over the interior
/// pixels and over every pixel, each with the view's SSIM over the window
/// centres of that region (target pixels only): added to `totals`
/// (interior, whole) and returned for the view alone.
fn measure_view(
    scene: &Scene,
    f: usize,
    view: &RenderedView,
    margin: u32,
    totals: [&mut EvalAccumulator; 2],
) -> [EvalMetrics; 2] {
    let frame = &scene.frames[f];
    let mut interior = EvalAccumulator::default();
    let mut whole = EvalAccumulator::default();
    let [total_interior, total_whole] = totals;
    let (w, h) = (view.width, view.height);
    let ((x0, x1), (y0, y1)) = datasets::sampler::interior(margin, w, h);
    let inside = |x: u32, y: u32| (x0..x1).contains(&x) && (y0..y1).contains(&y);
    let lifted = (view.feature_dim > 0).then(|| lift_features(scene, view.feature.clone()));
    let full = scene.features.as_ref().map_or(0, |fs| fs.full_dim);
    for y in 0..h {
        for x in 0..w {
            // Masked-out pixels are no target, in evaluation as in training.
            if !frame.is_target_pixel(x, y) {
                continue;
            }
            let p = (y * w + x) as usize;
            let depth = frame.depth.as_ref().map(|d| (view.depth[p], d.get(x, y)));
            let target = scene.features.as_ref().and_then(|fs| {
                let t = fs.target(f, x as f64, y as f64, w, h)?;
                Some(lift_features(scene, t.iter().map(|v| v.to_f32()).collect()))
            });
            let feature = match (&lifted, &target) {
                (Some(l), Some(t)) => Some((&l[p * full..(p + 1) * full], t.as_slice())),
                _ => None,
            };
            let rgb = [view.rgb[3 * p], view.rgb[3 * p + 1], view.rgb[3 * p + 2]];
            let target_rgb = frame.rgb.get(x, y);
            whole.add(rgb, target_rgb, depth, feature);
            total_whole.add(rgb, target_rgb, depth, feature);
            if inside(x, y) {
                interior.add(rgb, target_rgb, depth, feature);
                total_interior.add(rgb, target_rgb, depth, feature);
            }
        }
    }
    if (frame.rgb.width, frame.rgb.height) == (w, h)
        && let Some(map) = ssim_map(&view.rgb, &frame.rgb.to_f32(), w, h)
    {
        let target = |x: u32, y: u32| frame.is_target_pixel(x, y);
        let ssim_whole = map.mean_where(target);
        let ssim_interior = map.mean_where(|x, y| target(x, y) && inside(x, y));
        whole.add_ssim(ssim_whole);
        total_whole.add_ssim(ssim_whole);
        interior.add_ssim(ssim_interior);
        total_interior.add_ssim(ssim_interior);
    }
    [interior.finish(), whole.finish()]
}
