//! Appearance codes in the renderer: they reach the colour branch only
//! (depth, opacity and weights are those of the zero code), a render with
//! no codes is the zero code's, and the inference pass renders what the
//! training pass renders without codes.

mod common;

use burn::tensor::{Device, Tensor, TensorData};
use common::{assert_close, camera_rays, tiny_config, vec};
use model::{AppearanceCodesConfig, PerPhotograph, RenderRequest, Termination};

#[test]
fn codes_change_the_colour_only_and_every_other_render_uses_the_zero_code() {
    let device = Device::flex();
    device.seed(11);
    let m = tiny_config()
        .with_num_samples(8)
        .with_appearance(Some(AppearanceCodesConfig::new(3).with_dim(5)))
        .init(&device);
    assert_eq!(m.radiance().appearance_dim(), 5);
    let rays = camera_rays(6, 3);
    let request = RenderRequest::train(&rays).with_randomized(false);
    let with = |code: Tensor<2>| {
        m.render_train_with(
            &request,
            PerPhotograph {
                pose_correction: None,
                appearance: Some(code),
            },
        )
    };
    let none = m.render(&request);
    let zero = with(Tensor::zeros([6, 5], &device));
    let values: Vec<f32> = (0..30).map(|i| ((i * 7) % 11) as f32 / 5.0 - 1.0).collect();
    let coded = with(Tensor::from_data(TensorData::new(values, [6, 5]), &device));
    let what = "zero code";
    assert_close(
        &vec(zero.fine.rgb.clone()),
        &vec(none.fine.rgb.clone()),
        1e-6,
        1e-6,
        what,
    );
    let diff: f32 = vec(coded.fine.rgb.clone())
        .iter()
        .zip(vec(none.fine.rgb.clone()))
        .map(|(a, b)| (a - b).abs())
        .sum();
    assert!(diff > 1e-3, "a code changes the colour: {diff}");
    for (a, b, name) in [
        (&coded.fine.depth, &none.fine.depth, "depth"),
        (&coded.fine.acc, &none.fine.acc, "opacity"),
        (&coded.fine.weights, &none.fine.weights, "weights"),
    ] {
        assert_close(&vec(a.clone()), &vec(b.clone()), 1e-6, 1e-6, name);
    }
    let marched = m
        .render(&RenderRequest::inference(&rays).with_termination(Termination::off()))
        .expect("no observer");
    assert_close(&marched.rgb, &vec(none.fine.rgb), 2e-5, 2e-5, "inference");
}
