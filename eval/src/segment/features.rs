//! Features at the evaluation points: sampled from the field at each
//! point, or projected from rendered (or 2D) feature images with the
//! occlusion test.

use datasets::FeatureMap;
use datasets::features::FeatureSet;
use model::OpenNerf;
use model::geometry::{SceneBox, Vec3};

use field_ops::OpsError;
use field_ops::project::{DepthRef, FeatureAccumulator, Hit, ProjectOptions};
use field_ops::render::{ViewSettings, render_view};

use super::{SegmentOptions, View};

/// Index of the pixel of a `fw x fh` image at image point `(u, v)` of a
/// `w x h` camera (pixel centres at integers; nearest after scaling).
pub fn scaled_index(u: f64, v: f64, w: u32, h: u32, fw: u32, fh: u32) -> usize {
    let x = (((u + 0.5) * fw as f64 / w as f64).floor().max(0.0) as usize).min(fw as usize - 1);
    let y = (((v + 0.5) * fh as f64 / h as f64).floor().max(0.0) as usize).min(fh as usize - 1);
    y * fw as usize + x
}

/// Averages rendered feature images over `views`: each view is rendered at
/// `render_scale` of its resolution; a point takes the feature of the pixel
/// it lands on when it passes the occlusion test against the view's sensor
/// depth (or the rendered depth without one). Sums stay in the field's
/// output space (k channels), so memory is `points * k` floats.
pub fn projected_features(
    model: &OpenNerf,
    points: &[Vec3],
    views: &[View<'_>],
    scene_box: &SceneBox,
    background: Option<[f32; 3]>,
    opts: &SegmentOptions,
    mut progress: impl FnMut(usize, usize),
) -> Result<FeatureAccumulator, OpsError> {
    let mut acc: Option<FeatureAccumulator> = None;
    for (vi, view) in views.iter().enumerate() {
        let k = &view.camera.intrinsics;
        let (rw, rh) = (
            ((k.width as f64 * opts.render_scale).round() as u32).max(1),
            ((k.height as f64 * opts.render_scale).round() as u32).max(1),
        );
        let cam = view.camera.scaled(rw, rh);
        let settings = ViewSettings::new(background, opts.chunk).with_features(true);
        let r = render_view(model, &cam, scene_box, &settings)
            .expect("never cancelled without an observer");
        if r.feature_dim == 0 {
            return Err(OpsError::Invalid("the model renders no features".into()));
        }
        let a = acc.get_or_insert_with(|| FeatureAccumulator::new(points.len(), r.feature_dim));
        let values = view.depth.map(|d| d.to_f32());
        let depth = match view.depth.zip(values.as_deref()) {
            Some((d, data)) => DepthRef {
                width: d.width,
                height: d.height,
                data,
            },
            None => DepthRef {
                width: rw,
                height: rh,
                data: &r.depth,
            },
        };
        let dim = r.feature_dim;
        a.add_view(
            points,
            &view.camera,
            Some(depth),
            &opts.project,
            |h: &Hit, out| {
                let i = scaled_index(h.u, h.v, k.width, k.height, rw, rh);
                out.copy_from_slice(&r.feature[i * dim..(i + 1) * dim]);
                true
            },
        );
        progress(vi + 1, views.len());
    }
    acc.ok_or_else(|| OpsError::Invalid("no views to project into".into()))
}

/// The upper bound without a field: the scene's own 2D feature maps
/// projected onto the points (sensor depth for the occlusion test) and
/// averaged, in the maps' (possibly PCA) space. Map pixels without a target
/// (see [`datasets::features::FeatureSet::is_target`]) are skipped.
pub fn projected_2d_features(
    set: &FeatureSet,
    maps: &[&FeatureMap],
    views: &[View<'_>],
    points: &[Vec3],
    opts: &ProjectOptions,
) -> Result<FeatureAccumulator, OpsError> {
    let dim = maps.first().map_or(0, |m| m.dim);
    if maps.len() != views.len() || dim == 0 {
        return Err(OpsError::Invalid(format!(
            "{} feature maps for {} views",
            maps.len(),
            views.len()
        )));
    }
    let mut acc = FeatureAccumulator::new(points.len(), dim);
    for (m, view) in maps.iter().zip(views) {
        let k = &view.camera.intrinsics;
        let values = view.depth.map(|d| d.to_f32());
        let depth = view.depth.zip(values.as_deref()).map(|(d, data)| DepthRef {
            width: d.width,
            height: d.height,
            data,
        });
        acc.add_view(points, &view.camera, depth, opts, |h, out| {
            let f = m.lookup(h.u, h.v, k.width, k.height);
            if !set.is_target(f) {
                return false;
            }
            out.iter_mut().zip(f).for_each(|(o, x)| *o = x.to_f32());
            true
        });
    }
    Ok(acc)
}
