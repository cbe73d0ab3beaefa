//! Whole-model behaviour: stop-gradient of the open-set head, the composited
//! feature path, top-k head evaluation, overfitting, save/load, point queries
//! and numerical extremes of full rendering.
// Index loops mirror the formulas in these reference computations.
#![allow(clippy::needless_range_loop)]

mod common;

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::{AdamConfig, GradientsParams};
use burn::tensor::{Device, Gradients, Tensor};
use common::{assert_close, camera_rays, devices, tensor, vec};
use model::geometry::{NormalizedRay, SceneBox};
use model::{
    FeatureHeadConfig, FeatureMode, FeatureSpace, MipMlpConfig, OpenNerf, OpenNerfConfig, Rays,
    RenderOutputs, RenderRequest, Termination, open_set_cosine, rgb_mse,
};

/// The dense render of `rays` (jitter as `randomized` says, composited
/// features unless `mode` says otherwise), no background.
fn dense(
    model: &OpenNerf,
    rays: &[NormalizedRay],
    randomized: bool,
    mode: FeatureMode,
) -> RenderOutputs {
    let request = RenderRequest::train(rays)
        .with_randomized(randomized)
        .with_features(mode);
    model.render(&request)
}

fn small_config(out_dim: usize, samples: usize) -> OpenNerfConfig {
    OpenNerfConfig::new(FeatureHeadConfig::new(out_dim).with_width(16))
        .with_mlp(
            MipMlpConfig::new()
                .with_depth(4)
                .with_width(32)
                .with_skip_layer(2)
                .with_max_deg(8),
        )
        .with_num_samples(samples)
}

/// Largest absolute gradient of each float parameter (0 when absent).
struct GradMax<'a> {
    grads: &'a Gradients,
    found: Vec<(usize, f32)>,
}

impl ModuleVisitor for GradMax<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let m = match param.val().grad(self.grads) {
            Some(g) => g.abs().max().into_scalar::<f32>(),
            None => 0.0,
        };
        self.found.push((param.val().shape().num_elements(), m));
    }
}

fn grad_max<M: Module>(module: &M, grads: &Gradients) -> Vec<(usize, f32)> {
    let mut v = GradMax {
        grads,
        found: Vec::new(),
    };
    module.visit(&mut v);
    v.found
}

/// The open-set loss alone gives exactly zero gradient on every MLP
/// parameter (trunk, density, colour) and a non-zero one on the head; the
/// colour loss gives zero on the head.
#[test]
fn open_set_loss_does_not_reach_density_or_colour() {
    for (name, device) in devices(false) {
        let device = device.autodiff();
        device.seed(11);
        let model = small_config(8, 8).init(&device);
        let rays = camera_rays(16, 1);
        let target = Tensor::<2>::random(
            [16, 8],
            burn::tensor::Distribution::Normal(0.0, 1.0),
            &device,
        );

        for mode in [FeatureMode::Composited, FeatureMode::PerSample] {
            let out = dense(&model, &rays, true, mode);
            let feat = out.fine.feature.expect("fine feature");
            let mask = Tensor::<2>::ones([16, 1], &device);
            let grads =
                open_set_cosine(feat, target.clone(), mask, &FeatureSpace::Identity).backward();
            let mlp = grad_max(&model.mlp, &grads);
            assert!(mlp.len() >= 12, "{name}: visited {} MLP params", mlp.len());
            assert!(
                mlp.iter().all(|&(_, g)| g == 0.0),
                "{name} {mode:?}: open-set loss reached the MLP: {mlp:?}"
            );
            let head = grad_max(&model.head, &grads);
            assert!(
                head.iter().all(|&(_, g)| g > 0.0),
                "{name} {mode:?}: head gradient missing: {head:?}"
            );
        }

        let out = model.render(&RenderRequest::train(&rays));
        let target_rgb = Tensor::<2>::random(
            [16, 3],
            burn::tensor::Distribution::Uniform(0.0, 1.0),
            &device,
        );
        let loss = rgb_mse(out.fine.rgb, target_rgb.clone()).add(rgb_mse(
            out.coarse.as_ref().expect("coarse level").rgb.clone(),
            target_rgb,
        ));
        let grads = loss.backward();
        let head = grad_max(&model.head, &grads);
        assert!(
            head.iter().all(|&(_, g)| g == 0.0),
            "{name}: colour loss reached the head"
        );
        let mlp = grad_max(&model.mlp, &grads);
        assert!(
            mlp.iter().any(|&(_, g)| g > 0.0),
            "{name}: colour loss must train the MLP"
        );
    }
}

/// Compositing hidden activations and applying the output layer once per ray
/// equals applying the head per sample and compositing; top-k with k equal to
/// the sample count equals the full path; coarse features when configured.
#[test]
fn composited_head_equals_per_sample_head() {
    for (name, device) in devices(true) {
        device.seed(5);
        let cfg = small_config(6, 8).with_coarse_features(true);
        let model = cfg.init(&device);
        let rays = camera_rays(12, 2);
        let a = dense(&model, &rays, false, FeatureMode::Composited);
        let b = dense(&model, &rays, false, FeatureMode::PerSample);
        for (lvl, x, y) in [
            ("fine", &a.fine.feature, &b.fine.feature),
            (
                "coarse",
                &a.coarse.as_ref().expect("coarse level").feature,
                &b.coarse.as_ref().expect("coarse level").feature,
            ),
        ] {
            let (x, y) = (
                vec(x.clone().expect("feature")),
                vec(y.clone().expect("feature")),
            );
            assert!(
                y.iter().any(|v| v.abs() > 1e-3),
                "{name}: degenerate features"
            );
            assert_close(&x, &y, 1e-5, 1e-4, &format!("{name} {lvl}"));
        }
        // Top-k with k = samples, built from the same weights.
        let top = cfg
            .clone()
            .with_head_top_k(Some(8))
            .init(&device)
            .load_record(model.clone().into_record());
        let c = dense(&top, &rays, false, FeatureMode::Composited);
        let x = vec(c.fine.feature.expect("feature"));
        let y = vec(b.fine.feature.expect("feature"));
        assert_close(&x, &y, 1e-5, 1e-4, &format!("{name} top-k = all"));
    }
}

/// Top-k with k = 1 on rays whose fine weights are concentrated: the feature
/// equals `w_max A h_max + b w_max`, computed here from the per-sample head.
#[test]
fn top_k_one_uses_the_heaviest_sample() {
    let device = Device::flex();
    device.seed(9);
    let cfg = small_config(4, 6);
    let model = cfg.init(&device);
    let top = cfg
        .clone()
        .with_head_top_k(Some(1))
        .init(&device)
        .load_record(model.clone().into_record());
    let host_rays = camera_rays(5, 3);
    let rays = Rays::from_normalized(&host_rays, &device);
    let out = top.render(&RenderRequest::train(&host_rays).with_randomized(false));
    let got = vec(out.fine.feature.expect("feature"));
    // Per-sample reference at the same fine posts.
    let full = dense(&model, &host_rays, false, FeatureMode::PerSample);
    assert_close(
        &vec(full.fine.t_vals.clone()),
        &vec(out.fine.t_vals.clone()),
        0.0,
        0.0,
        "same posts",
    );
    let w = vec(out.fine.weights.clone());
    let g = model::mip::cast_rays(
        out.fine.t_vals,
        rays.origins.clone(),
        rays.directions.clone(),
        rays.radii.clone(),
    );
    let ipe = model::mip::integrated_pos_enc(g.mean, g.cov_diag, 0, 8);
    let [n, s, c] = ipe.dims();
    let (trunk, _) = model.radiance().trunk_density(ipe.reshape([n * s, c]));
    let per_sample = vec(model.head.forward(trunk));
    for r in 0..n {
        let row = &w[r * s..(r + 1) * s];
        let (imax, wmax) = row
            .iter()
            .enumerate()
            .fold((0, -1.0f32), |a, (i, &v)| if v > a.1 { (i, v) } else { a });
        // The weighted mean over one sample is that sample's feature.
        assert!(wmax > 0.0);
        let want: Vec<f32> = (0..4).map(|k| per_sample[(r * s + imax) * 4 + k]).collect();
        assert_close(
            &got[r * 4..r * 4 + 4],
            &want,
            1e-5,
            1e-4,
            &format!("ray {r}"),
        );
    }
}

/// A small model drives the colour loss on one fixed batch down by 10x.
#[test]
fn overfits_a_fixed_batch() {
    let device = Device::flex().autodiff();
    device.seed(1);
    let mut model: OpenNerf = small_config(4, 16).init(&device);
    let rays_cpu = camera_rays(64, 4);
    // Smooth colours as a function of the direction.
    let target: Vec<f32> = rays_cpu
        .iter()
        .flat_map(|r| {
            let d = r.direction;
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            [
                0.5 + 0.4 * (8.0 * d[0] / n).sin(),
                0.5 + 0.4 * (8.0 * d[1] / n).cos(),
                0.3,
            ]
        })
        .collect();
    let target = tensor(target, [64, 3], &device);
    let mut optim = AdamConfig::new().init();
    let mut first = None;
    let mut last = 0.0;
    for _ in 0..150 {
        let out = model.render(&RenderRequest::train(&rays_cpu));
        let loss = rgb_mse(out.fine.rgb, target.clone()).add(
            rgb_mse(
                out.coarse.as_ref().expect("coarse level").rgb.clone(),
                target.clone(),
            )
            .mul_scalar(0.1),
        );
        let value = loss.clone().into_scalar::<f32>();
        first.get_or_insert(value);
        last = value;
        let grads = GradientsParams::from_grads(loss.backward(), &model);
        model = optim.step(5e-3, model, grads);
    }
    let first = first.unwrap_or(f32::NAN);
    println!("colour loss {first:.5} -> {last:.5}");
    assert!(
        last.is_finite() && last * 10.0 <= first,
        "loss {first} -> {last}"
    );
}

/// Saving and loading the record reproduces the outputs exactly.
#[test]
fn save_load_round_trip() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("model.bpk");
    let device = Device::flex();
    device.seed(2);
    let cfg = small_config(5, 8);
    let model = cfg.init(&device);
    let rays = camera_rays(6, 5);
    let white = RenderRequest::train(&rays)
        .with_randomized(false)
        .with_background(Some([1.0, 1.0, 1.0]));
    let a = model.render(&white);
    model.clone().save_file(&path).expect("save");
    device.seed(3);
    let fresh = cfg.init(&device);
    let before = dense(&fresh, &rays, false, FeatureMode::Composited);
    assert_ne!(
        vec(before.fine.rgb),
        vec(a.fine.rgb.clone()),
        "fresh init must differ"
    );
    let loaded = fresh.load_file(&path);
    let b = loaded.render(&white);
    assert_eq!(vec(a.fine.rgb), vec(b.fine.rgb));
    assert_eq!(vec(a.fine.depth), vec(b.fine.depth));
    assert_eq!(
        vec(a.fine.feature.expect("f")),
        vec(b.fine.feature.expect("f"))
    );
}

/// Chunked inference equals one deterministic render; point queries agree
/// with the head and density of the trunk at a tiny-radius Gaussian.
#[test]
fn inference_chunks_and_point_queries() {
    for (name, device) in devices(false) {
        device.seed(4);
        let model = small_config(3, 8).init(&device);
        let rays = camera_rays(10, 6);
        let whole = dense(&model, &rays, false, FeatureMode::Composited);
        let inference = |mode| {
            let request = RenderRequest::inference(&rays)
                .with_chunk(3)
                .with_termination(Termination::off())
                .with_features(mode);
            model.render(&request).expect("no observer")
        };
        let chunked = inference(FeatureMode::Composited);
        // Without the feature head: same colour and depth, no feature image
        // (at either level of the dense render).
        let plain = inference(FeatureMode::None);
        assert!(plain.feature.is_empty() && plain.feature_dim == 0);
        let plain_dense = dense(&model, &rays, false, FeatureMode::None);
        assert!(
            plain_dense.fine.feature.is_none()
                && plain_dense
                    .coarse
                    .as_ref()
                    .expect("coarse level")
                    .feature
                    .is_none()
        );
        assert_close(&plain.rgb, &vec(whole.fine.rgb.clone()), 1e-6, 1e-5, name);
        assert_close(
            &plain.depth,
            &vec(whole.fine.depth.clone()),
            1e-5,
            1e-5,
            name,
        );
        assert_close(&chunked.rgb, &vec(whole.fine.rgb), 1e-6, 1e-5, name);
        assert_close(&chunked.depth, &vec(whole.fine.depth), 1e-5, 1e-5, name);
        assert_close(
            &chunked.feature,
            &vec(whole.fine.feature.expect("f")),
            1e-5,
            1e-4,
            name,
        );
        let pts = tensor(vec![0.1, 0.2, 0.3, -1.0, 0.5, 2.0], [2, 3], &device);
        let f = model.query_features(pts.clone(), 1e-4);
        let d = model.query_density(pts.clone(), 1e-4);
        assert_eq!(f.dims(), [2, 3]);
        assert_eq!(d.dims(), [2, 1]);
        assert!(vec(d.clone()).iter().all(|v| v.is_finite() && *v >= 0.0));
        // A huge radius integrates every frequency away: the outputs no longer
        // depend on the position.
        let far = vec(model.query_features(pts, 1e4));
        assert_close(
            &far[..3],
            &far[3..],
            1e-6,
            0.0,
            &format!("{name} huge radius"),
        );
    }
}

/// Extremes through the whole model: near == far, axis-parallel rays, one
/// sample per ray, and a scene at +-1e4 m normalised by its box.
#[test]
fn render_extremes_stay_finite() {
    for (name, device) in devices(false) {
        device.seed(6);
        let scene = SceneBox {
            min: [1e4 - 2.0, -1e4 - 2.0, 1e4 - 2.0],
            max: [1e4 + 2.0, -1e4 + 2.0, 1e4 + 2.0],
        };
        let c = scene.center();
        let base = model::geometry::Ray {
            origin: [c[0], c[1], c[2] - 5.0],
            direction: [0.0, 0.0, 1.0],
            radius: 1e-3,
        };
        let mut rays = vec![scene.normalize_ray(&base, 0.05)];
        // Axis-parallel along x and y, a ray missing the box (near == far) and
        // an explicit degenerate ray.
        rays.push(scene.normalize_ray(
            &model::geometry::Ray {
                origin: [c[0] - 5.0, c[1], c[2]],
                direction: [1.0, 0.0, 0.0],
                ..base
            },
            0.05,
        ));
        rays.push(scene.normalize_ray(
            &model::geometry::Ray {
                origin: [c[0], c[1] + 5.0, c[2]],
                direction: [0.0, -1.0, 0.0],
                ..base
            },
            0.05,
        ));
        rays.push(scene.normalize_ray(
            &model::geometry::Ray {
                direction: [0.0, 0.0, -1.0],
                ..base
            },
            0.05,
        ));
        let mut degenerate = rays[0];
        degenerate.far = degenerate.near;
        rays.push(degenerate);
        assert_eq!(rays[3].near, rays[3].far, "missing ray must be empty");
        assert!(rays[0].near < rays[0].far && rays[1].near < rays[1].far);
        for samples in [1, 8] {
            let model = small_config(3, samples).init(&device);
            for randomized in [false, true] {
                let request = RenderRequest::train(&rays)
                    .with_randomized(randomized)
                    .with_background(Some([0.5, 0.5, 0.5]));
                let out = model.render(&request);
                for (what, t) in [
                    ("rgb", out.fine.rgb.clone()),
                    ("depth", out.fine.depth.clone()),
                    ("acc", out.fine.acc.clone()),
                    ("feature", out.fine.feature.clone().expect("f")),
                    ("weights", out.fine.weights.clone()),
                    ("t_vals", out.fine.t_vals.clone()),
                    (
                        "coarse rgb",
                        out.coarse.as_ref().expect("coarse level").rgb.clone(),
                    ),
                ] {
                    let v = vec(t);
                    assert!(
                        v.iter().all(|x| x.is_finite()),
                        "{name} s={samples}: {what} {v:?}"
                    );
                }
                let acc = vec(out.fine.acc);
                let rgb = vec(out.fine.rgb);
                // Empty rays: no opacity, background colour, zero depth.
                for i in [3, 4] {
                    assert_eq!(acc[i], 0.0, "{name}: empty ray {i}");
                    assert_close(&rgb[3 * i..3 * i + 3], &[0.5; 3], 1e-6, 0.0, name);
                }
                // Posts stay inside [near, far].
                let t = vec(out.fine.t_vals);
                for (i, ray) in rays.iter().enumerate() {
                    let row = &t[i * (samples + 1)..(i + 1) * (samples + 1)];
                    assert!(
                        row.iter()
                            .all(|&v| v >= ray.near - 1e-4 && v <= ray.far + 1e-4),
                        "{name}: posts {row:?}"
                    );
                }
            }
        }
    }
}

/// The feature of a ray is the weighted *mean* of its samples' features:
/// with a head whose output is the constant `b`, every ray's feature is `b`,
/// also where the opacity is far below 1 (short rays through thin density).
/// Without the division by the opacity it would be `acc * b`, which after a
/// PCA lift `m + U^T c` pulls such pixels towards the scene mean.
#[test]
fn features_are_weighted_means_also_where_acc_is_below_one() {
    for (name, device) in devices(false) {
        device.seed(5);
        let mut model = small_config(3, 8).init(&device);
        let b = [0.7f32, -1.3, 2.0];
        let w = model.head.output.weight.val();
        model.head.output.weight = Param::from_tensor(w.zeros_like());
        model.head.output.bias = Some(Param::from_tensor(tensor(b.to_vec(), [3], &device)));
        // Short rays (far - near = 0.02 normalised units) keep acc small.
        let rays: Vec<NormalizedRay> = camera_rays(12, 3)
            .into_iter()
            .map(|mut r| {
                r.far = r.near + 0.02;
                r
            })
            .collect();
        for mode in [FeatureMode::Composited, FeatureMode::PerSample] {
            let out = dense(&model, &rays, false, mode).fine;
            let acc = vec(out.acc);
            assert!(
                acc.iter().all(|&a| a > 1e-4 && a < 0.5),
                "{name}: acc {acc:?}"
            );
            let f = vec(out.feature.expect("feature"));
            let want: Vec<f32> = (0..12).flat_map(|_| b).collect();
            assert_close(&f, &want, 1e-4, 1e-4, &format!("{name} {mode:?}"));
        }
    }
}
