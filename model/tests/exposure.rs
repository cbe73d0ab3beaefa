//! The learned exposure of the training photographs: the correction
//! against its float64 formula, each ray's row, the penalty, and a field
//! whose configuration has none (every run before it) loading as before.

mod common;

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::{Device, Tensor};
use common::{assert_close, devices, tensor, uniform, vec};
use model::exposure::{expose, exposure_penalty};
use model::{ExposureConfig, FeatureHeadConfig, MipMlpConfig, OpenNerfConfig};

/// Deterministic values in `[lo, hi)`.
fn values(n: usize, seed: u64, lo: f32, hi: f32) -> Vec<f32> {
    uniform(n, seed, lo as f64, hi as f64)
        .into_iter()
        .map(|x| x as f32)
        .collect()
}

#[test]
fn the_correction_is_a_gain_and_an_offset_per_channel() {
    let n = 37;
    let rgb = values(n * 3, 1, 0.0, 1.0);
    let correction = values(n * 6, 2, -0.7, 0.7);
    let expected: Vec<f32> = (0..n * 3)
        .map(|i| {
            let (ray, c) = (i / 3, i % 3);
            let gain = (correction[ray * 6 + c] as f64).exp();
            (rgb[i] as f64 * gain + correction[ray * 6 + 3 + c] as f64) as f32
        })
        .collect();
    for (name, device) in devices(true) {
        let out = expose(
            tensor(rgb.clone(), [n, 3], &device),
            tensor(correction.clone(), [n, 6], &device),
        );
        assert_close(&vec(out), &expected, 1e-6, 1e-5, name);
        let penalty = vec(exposure_penalty(tensor(
            correction.clone(),
            [n, 6],
            &device,
        )))[0];
        let brute = correction.iter().map(|&c| c as f64 * c as f64).sum::<f64>() / n as f64;
        assert!(
            (penalty as f64 - brute).abs() < 1e-5 * brute,
            "{name}: {penalty} vs {brute}"
        );
    }
}

#[test]
fn each_ray_takes_its_photographs_row_and_other_frames_none() {
    let device = Device::flex();
    let mut exposure = ExposureConfig::new(3).init(&device);
    // A fresh table corrects nothing.
    let fresh = vec(exposure.per_ray(&[0, 1, 2, 3, 9]));
    assert!(fresh.iter().all(|&v| v == 0.0), "{fresh:?}");
    let table = values(18, 3, -1.0, 1.0);
    exposure.params = Param::from_tensor(tensor(table.clone(), [3, 6], &device));
    // Frames 3 and 9 (past the photographs: novel views) get none.
    let frames = [2, 0, 3, 1, 9, 2];
    let got = vec(exposure.per_ray(&frames));
    let expected: Vec<f32> = frames
        .iter()
        .flat_map(|&f| {
            if f < 3 {
                table[f * 6..f * 6 + 6].to_vec()
            } else {
                vec![0.0; 6]
            }
        })
        .collect();
    assert_eq!(got, expected);
    // Uncorrected rays keep their colour exactly.
    let rgb = values(frames.len() * 3, 4, 0.0, 1.0);
    let out = vec(expose(
        tensor(rgb.clone(), [frames.len(), 3], &device),
        exposure.per_ray(&frames),
    ));
    assert_eq!(&out[6..9], &rgb[6..9]);
    assert_eq!(&out[12..15], &rgb[12..15]);
}

#[test]
fn only_the_rows_of_the_batchs_photographs_get_gradients() {
    let device = Device::flex().autodiff();
    let exposure = ExposureConfig::new(4).init(&device);
    let rgb = tensor(values(15, 5, 0.1, 0.9), [5, 3], &device);
    let c = exposure.per_ray(&[1, 3, 1, 7, 3]);
    let loss = expose(rgb, c.clone()).sum() + exposure_penalty(c);
    let grads = loss.backward();
    let g = exposure.params.grad(&grads).expect("a gradient");
    let g: Vec<f32> = g.try_into_vec_as::<f32>().expect("f32");
    for (row, chunk) in g.chunks(6).enumerate() {
        let moved = chunk.iter().any(|&v| v != 0.0);
        assert_eq!(moved, row == 1 || row == 3, "row {row}: {chunk:?}");
    }
}

fn config(exposure: Option<ExposureConfig>) -> OpenNerfConfig {
    let mut c = OpenNerfConfig::new(FeatureHeadConfig::new(4).with_width(8))
        .with_mlp(
            MipMlpConfig::new()
                .with_width(16)
                .with_depth(2)
                .with_skip_layer(1)
                .with_max_deg(4),
        )
        .with_num_samples(8);
    c.exposure = exposure;
    c
}

struct Count(usize);

impl ModuleVisitor for Count {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        self.0 += p.val().shape().num_elements();
    }
}

#[test]
fn a_configuration_without_exposure_loads_as_before_and_one_with_it_round_trips() {
    let device = Device::flex();
    // A run written before this key existed.
    let mut old = serde_json::to_value(config(None)).expect("json");
    old.as_object_mut().expect("object").remove("exposure");
    let loaded: OpenNerfConfig = serde_json::from_value(old).expect("an old configuration");
    assert!(loaded.exposure.is_none());
    let count = |c: &OpenNerfConfig| {
        let mut v = Count(0);
        c.init(&device).visit(&mut v);
        v.0
    };
    let with = config(Some(ExposureConfig::new(7)));
    let json = serde_json::to_string(&with).expect("json");
    let back: OpenNerfConfig = serde_json::from_str(&json).expect("round trip");
    assert_eq!(back.exposure.as_ref().map(|e| e.images), Some(7));
    // The corrections are weights of the field (saved, loaded, optimised):
    // 7 photographs x 6 numbers more than the field without them.
    assert_eq!(count(&back), count(&loaded) + 42);
    // Saved and loaded with the rest of the weights.
    let mut field = back.init(&device);
    let table = values(42, 6, -0.5, 0.5);
    field.exposure.as_mut().expect("exposure").params =
        Param::from_tensor(tensor(table.clone(), [7, 6], &device));
    let path = std::env::temp_dir().join(format!("opennerf-exposure-{}.bpk", std::process::id()));
    field.clone().save_file(&path).expect("weights written");
    let bytes = std::fs::read(&path).expect("weights read");
    std::fs::remove_file(&path).ok();
    let record = burn::store::ModuleRecord::from_bytes(burn::tensor::Bytes::from_bytes_vec(bytes))
        .expect("a burnpack");
    let reloaded = back
        .init(&device)
        .try_load_record(record)
        .expect("weights match");
    let got = vec(reloaded.exposure.expect("exposure").params.val());
    assert_eq!(got, table);
}
