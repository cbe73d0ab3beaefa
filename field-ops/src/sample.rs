//! Field features sampled at world points (the field queried directly,
//! no view): what `eval segment --mode sampled`, relevancy on points and the
//! viewer colour points with.

use burn::tensor::{Device, Tensor, TensorData};
use model::OpenNerf;
use model::geometry::{SceneBox, Vec3};

use crate::render::tensor_to_vec;

/// Field features at world points, `[n, k]` row-major: points are
/// normalised into `scene_box` and encoded as isotropic Gaussians of
/// standard deviation `radius` metres.
pub fn sampled_features(
    model: &OpenNerf,
    points: &[Vec3],
    scene_box: &SceneBox,
    radius: f64,
    chunk: usize,
    device: &Device,
) -> Vec<f32> {
    let r = (radius * scene_box.scale()) as f32;
    let mut out = Vec::new();
    for part in points.chunks(chunk.max(1)) {
        let flat: Vec<f32> = part
            .iter()
            .flat_map(|&p| scene_box.normalize_point(p).map(|x| x as f32))
            .collect();
        let t = Tensor::<2>::from_data(TensorData::new(flat, [part.len(), 3]), device);
        out.extend(tensor_to_vec(model.query_features(t, r)));
    }
    out
}
