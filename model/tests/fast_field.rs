//! The fast field against independent references: its view encoding's
//! spherical harmonics are orthonormal over the sphere (Monte Carlo) and
//! satisfy the addition theorem at every direction; its gradients match
//! finite differences; the open-set head's loss leaves the field alone;
//! the inference pass renders what the training pass does; its weights
//! round-trip; and a field that trains it learns a scene.

mod common;

use burn::module::{Module, Param};
use burn::tensor::{Device, Tensor};
use common::{assert_close, camera_rays, devices, tensor, uniform, vec};
use model::fast_field::exp_density;
use model::sh::{sh_dim, sh_encoding};
use model::{
    FastFieldConfig, FeatureHeadConfig, FeatureMode, HashGridConfig, OpenNerf, OpenNerfConfig,
    ProposalConfig, Radiance, RenderRequest, Termination,
};

/// Unit directions uniform on the sphere (normalised Gaussian triples).
fn directions(n: usize, seed: u64) -> Vec<f32> {
    let u = uniform(2 * n, seed, 1e-12, 1.0);
    let mut out = Vec::with_capacity(3 * n);
    for i in 0..n {
        // Uniform z and azimuth give a uniform point on the sphere.
        let z = 2.0 * u[2 * i] - 1.0;
        let phi = 2.0 * std::f64::consts::PI * u[2 * i + 1];
        let r = (1.0 - z * z).max(0.0).sqrt();
        out.extend([(r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32]);
    }
    out
}

/// `∫ Y_i Y_j dω = δ_ij`: 4π times the mean of `Y_i Y_j` over uniform
/// directions, in float64, is the identity within the Monte Carlo error.
#[test]
fn spherical_harmonics_are_orthonormal_over_the_sphere() {
    let device = Device::flex();
    let n = 200_000;
    let dirs = tensor(directions(n, 3), [n, 3], &device);
    let y = vec(sh_encoding(dirs, 4));
    let k = sh_dim(4);
    assert_eq!(k, 16);
    for i in 0..k {
        for j in 0..=i {
            let mean: f64 = (0..n)
                .map(|r| y[r * k + i] as f64 * y[r * k + j] as f64)
                .sum::<f64>()
                / n as f64;
            let got = 4.0 * std::f64::consts::PI * mean;
            let want = if i == j { 1.0 } else { 0.0 };
            assert!(
                (got - want).abs() < 0.03,
                "<Y_{i}, Y_{j}> = {got}, expected {want}"
            );
        }
    }
}

/// The addition theorem: at every direction, the squares of a band's `2l
/// + 1` functions sum to `(2l + 1) / 4π`; and fewer bands are a prefix.
#[test]
fn each_band_sums_to_the_addition_theorem_at_every_direction() {
    let device = Device::flex();
    let n = 500;
    let dirs = tensor(directions(n, 8), [n, 3], &device);
    let y = vec(sh_encoding(dirs.clone(), 4));
    for r in 0..n {
        let mut start = 0;
        for l in 0..4 {
            let len = 2 * l + 1;
            let sum: f64 = (start..start + len)
                .map(|i| (y[r * 16 + i] as f64).powi(2))
                .sum();
            let want = len as f64 / (4.0 * std::f64::consts::PI);
            assert!((sum - want).abs() < 1e-5, "direction {r}, band {l}: {sum}");
            start += len;
        }
    }
    for degree in 1..4 {
        let fewer = vec(sh_encoding(dirs.clone(), degree));
        let k = degree * degree;
        for r in 0..n {
            assert_eq!(&fewer[r * k..(r + 1) * k], &y[r * 16..r * 16 + k]);
        }
    }
}

#[test]
fn the_density_is_an_exponential_capped_far_above_any_surface() {
    let device = Device::flex();
    let raw = tensor(vec![-3.0, 0.0, 2.5, 15.0, 40.0], [5, 1], &device);
    let got = vec(exp_density(raw));
    let want: Vec<f32> = [-3.0f32, 0.0, 2.5, 15.0, 15.0]
        .iter()
        .map(|v| v.exp())
        .collect();
    assert_close(&got, &want, 0.0, 1e-6, "exp density");
}

/// The density shift scales the field's density (and the proposal
/// network's) by `exp(shift)` and leaves its geometry feature and colour
/// alone.
#[test]
fn the_density_shift_scales_the_density_by_its_exponential() {
    let device = Device::flex();
    device.seed(9);
    let plain = varied(&fast_config(8, true), &device);
    let shift = -1.5f32;
    let mut shifted = plain.clone();
    shifted.fast.as_mut().expect("fast").density_shift = shift;
    shifted.proposal.as_mut().expect("proposal").density_shift = shift;
    let n = 12;
    let means = tensor(
        uniform(3 * n, 3, -3.0, 3.0)
            .into_iter()
            .map(|v| v as f32)
            .collect(),
        [n, 3],
        &device,
    );
    let cov = Tensor::<2>::zeros([n, 3], &device).add_scalar(1e-4);
    let scale = shift.exp();
    let field = |m: &OpenNerf| {
        let Radiance::Fast(fast) = m.radiance() else {
            panic!("the fast field");
        };
        let (geo, density) = fast.trunk_density(fast.encode(means.clone(), cov.clone()));
        (vec(geo), vec(density))
    };
    let (geo, density) = field(&plain);
    let (geo_s, density_s) = field(&shifted);
    assert_close(&geo_s, &geo, 0.0, 0.0, "geometry feature");
    let want: Vec<f32> = density.iter().map(|d| d * scale).collect();
    assert_close(&density_s, &want, 0.0, 1e-5, "field density");
    let proposal = |m: &OpenNerf| {
        let (_, mlp) = m.proposal_sampler().expect("proposal");
        vec(mlp.density_at(means.clone(), cov.clone()))
    };
    let want: Vec<f32> = proposal(&plain).iter().map(|d| d * scale).collect();
    assert_close(&proposal(&shifted), &want, 0.0, 1e-5, "proposal density");
}

fn fast_config(samples: usize, proposal: bool) -> OpenNerfConfig {
    let grid = HashGridConfig::new()
        .with_levels(4)
        .with_log2_table(10)
        .with_base_resolution(4)
        .with_max_resolution(64);
    let fast = FastFieldConfig::new()
        .with_grid(grid.clone())
        .with_density_width(16)
        .with_geo_features(7)
        .with_color_width(16);
    let proposal = proposal.then(|| {
        ProposalConfig::new()
            .with_samples(vec![16, 8])
            .with_depth(1)
            .with_width(8)
            .with_hash(Some(grid.with_levels(2).with_max_resolution(16)))
    });
    OpenNerfConfig::new(FeatureHeadConfig::new(5).with_width(8))
        .with_fast(Some(fast))
        .with_num_samples(samples)
        .with_proposal(proposal)
}

/// A fast-field model whose tables are drawn from `+-1` (not Instant-NGP's
/// `+-1e-4`), so that the field varies in space and the tests see it.
fn varied(config: &OpenNerfConfig, device: &Device) -> OpenNerf {
    let mut m = config.init(device);
    let fast = m.fast.as_mut().expect("the fast field");
    let dims = fast.grid.table.val().dims();
    fast.grid.table = Param::from_tensor(Tensor::random(
        dims,
        burn::tensor::Distribution::Uniform(-1.0, 1.0),
        device,
    ));
    m
}

#[test]
fn the_fast_field_replaces_the_mlp_and_its_head_reads_the_geometry_feature() {
    let device = Device::flex();
    let m = fast_config(8, false).init(&device);
    assert!(m.mlp.is_none() && m.hash.is_none());
    let Radiance::Fast(fast) = m.radiance() else {
        panic!("the fast field");
    };
    assert_eq!(fast.geo_features(), 7);
    assert_eq!(m.head.hidden[0].weight.dims(), [7, 8]);
    assert_eq!(fast.grid.output_dim(), 8);
    let params = m.num_params();
    let mip = OpenNerfConfig::new(FeatureHeadConfig::new(5).with_width(8))
        .init(&device)
        .num_params();
    assert!(params < mip / 5, "{params} vs the Mip-NeRF MLP's {mip}");
}

/// The gradient of a rendered colour and depth with respect to weights of
/// the density and colour MLPs and an entry of the table, against central
/// differences.
#[test]
fn gradients_match_finite_differences() {
    for footprint in [false, true] {
        gradients_match_finite_differences_with(footprint);
    }
}

fn gradients_match_finite_differences_with(footprint: bool) {
    let base = Device::flex();
    let device: Device = base.clone().autodiff();
    device.seed(4);
    let mut config = fast_config(8, false);
    config.fast = config
        .fast
        .map(|f| f.with_footprint_weights(Some(footprint)));
    let m = varied(&config, &device);
    let rays = camera_rays(6, 1);
    let loss = |m: &OpenNerf| -> Tensor<1> {
        // The coarse level: its posts are fixed, where the fine level's
        // move with the (detached) coarse weights.
        let out = m.render(&RenderRequest::train(&rays).with_randomized(false));
        let coarse = out.coarse.expect("the coarse level");
        let w = Tensor::<2>::from_data([[0.3f32, -0.7, 0.5]], &coarse.rgb.device());
        coarse
            .rgb
            .mul(w)
            .sum()
            .add(coarse.depth.sum().mul_scalar(0.1))
    };
    let grads = loss(&m).backward();
    let fast = m.fast.as_ref().expect("fast");
    let checks: Vec<(&str, Tensor<2>, Box<SetWeights>)> = vec![
        (
            "density_out",
            fast.density_out.weight.val(),
            Box::new(|m, t| m.fast.as_mut().unwrap().density_out.weight = Param::from_tensor(t)),
        ),
        (
            "color_geo",
            fast.color_geo.weight.val(),
            Box::new(|m, t| m.fast.as_mut().unwrap().color_geo.weight = Param::from_tensor(t)),
        ),
        (
            "table",
            fast.grid.table.val(),
            Box::new(|m, t| m.fast.as_mut().unwrap().grid.table = Param::from_tensor(t)),
        ),
    ];
    let plain = m.valid();
    for (name, weights, set) in checks {
        let analytic = vec(weights.grad(&grads).expect("a gradient"));
        let values = vec(weights.inner());
        let dims = plain_dims(&plain, name);
        // The entries with the largest gradients (where the difference is
        // well above rounding).
        let mut order: Vec<usize> = (0..values.len()).collect();
        order.sort_by(|&a, &b| analytic[b].abs().total_cmp(&analytic[a].abs()));
        for &k in order.iter().take(4) {
            let bump = |delta: f32| {
                let mut v = values.clone();
                v[k] += delta;
                let mut p = plain.clone();
                set(&mut p, tensor(v, dims, &base));
                vec(loss(&p))[0] as f64
            };
            let eps = 1e-3;
            let fd = (bump(eps) - bump(-eps)) / (2.0 * eps as f64);
            let g = analytic[k] as f64;
            assert!(
                (fd - g).abs() < 0.03 * g.abs().max(1e-2),
                "footprint weights {footprint}, {name}[{k}]: finite difference {fd}, gradient {g}"
            );
        }
    }
}

/// Puts a weight tensor back into a field.
type SetWeights = dyn Fn(&mut OpenNerf, Tensor<2>);

fn plain_dims(m: &OpenNerf, name: &str) -> [usize; 2] {
    let fast = m.fast.as_ref().expect("fast");
    match name {
        "density_out" => fast.density_out.weight.dims(),
        "color_geo" => fast.color_geo.weight.dims(),
        _ => fast.grid.table.dims(),
    }
}

/// The feature loss moves the head and nothing else: the head reads the
/// geometry feature detached, as it reads the Mip-NeRF trunk.
#[test]
fn the_feature_loss_leaves_the_field_alone() {
    let device: Device = Device::flex().autodiff();
    device.seed(6);
    let m = varied(&fast_config(8, true), &device);
    let rays = camera_rays(5, 2);
    let out = m.render(
        &RenderRequest::train(&rays)
            .with_randomized(false)
            .with_features(FeatureMode::Composited),
    );
    let grads = out.fine.feature.expect("a feature").sum().backward();
    let fast = m.fast.as_ref().expect("fast");
    assert!(fast.grid.table.val().grad(&grads).is_none());
    assert!(fast.density_out.weight.val().grad(&grads).is_none());
    let head = m
        .head
        .output
        .weight
        .val()
        .grad(&grads)
        .expect("the head learns");
    assert!(vec(head).iter().any(|&g| g != 0.0));
}

/// The field's configuration with a feature grid of 3 levels of 2
/// features for the open-set head.
fn with_feature_grid(mut config: OpenNerfConfig) -> OpenNerfConfig {
    let grid = HashGridConfig::new()
        .with_levels(3)
        .with_log2_table(9)
        .with_base_resolution(4)
        .with_max_resolution(32);
    config.fast = config.fast.map(|f| f.with_feature_grid(Some(grid)));
    config
}

/// With a feature grid, the head reads it beside the geometry feature;
/// the feature loss trains the feature grid and the head and leaves the
/// field alone, and the colour loss leaves the feature grid alone; the
/// inference pass renders the features the training pass does.
#[test]
fn a_feature_grid_is_the_heads_and_the_feature_losss_alone() {
    let device: Device = Device::flex().autodiff();
    device.seed(16);
    let mut m = varied(&with_feature_grid(fast_config(8, false)), &device);
    let fast = m.fast.as_mut().expect("fast");
    let grid = fast.feature_grid.as_mut().expect("a feature grid");
    let dims = grid.table.val().dims();
    grid.table = Param::from_tensor(Tensor::random(
        dims,
        burn::tensor::Distribution::Uniform(-1.0, 1.0),
        &device,
    ));
    let fast = m.fast.as_ref().expect("fast");
    assert_eq!(fast.trunk_width(), 7 + 6);
    assert_eq!(m.head.hidden[0].weight.dims(), [7 + 6, 8]);
    let rays = camera_rays(5, 2);
    let request = RenderRequest::train(&rays)
        .with_randomized(false)
        .with_features(FeatureMode::Composited);
    let out = m.render(&request).fine;
    let feature_grads = out.feature.expect("a feature").sum().backward();
    let table = |grads: &burn::tensor::Gradients| {
        fast.feature_grid
            .as_ref()
            .expect("a feature grid")
            .table
            .val()
            .grad(grads)
    };
    // The two grids' encodings travel together, and the trunk feature holds
    // both, so a loss may hand what it does not read a gradient of zeros.
    let zero = |g: Option<Tensor<2>>| g.is_none_or(|g| vec(g).iter().all(|&v| v == 0.0));
    let learned = table(&feature_grads).expect("the feature grid learns");
    assert!(vec(learned).iter().any(|&g| g != 0.0));
    assert!(zero(fast.grid.table.val().grad(&feature_grads)));
    assert!(zero(fast.density_out.weight.val().grad(&feature_grads)));
    let colour_grads = m.render(&request).fine.rgb.sum().backward();
    assert!(zero(table(&colour_grads)));
    assert!(!zero(fast.grid.table.val().grad(&colour_grads)));

    assert_the_march_renders_the_training_features(&m.valid(), &rays);
}

/// The march (without termination) renders the features and colours of
/// the plain deterministic training pass.
fn assert_the_march_renders_the_training_features(
    m: &OpenNerf,
    rays: &[model::geometry::NormalizedRay],
) {
    let want = m
        .render(
            &RenderRequest::train(rays)
                .with_randomized(false)
                .with_features(FeatureMode::Composited),
        )
        .fine;
    let off = Termination {
        transmittance: 0.0,
        segment: 3,
    };
    let got = m
        .render(
            &RenderRequest::inference(rays)
                .with_features(FeatureMode::Composited)
                .with_termination(off),
        )
        .expect("no observer");
    let want_feature = vec(want.feature.expect("a feature"));
    assert_close(&got.feature, &want_feature, 2e-5, 2e-5, "feature");
    assert_close(&got.rgb, &vec(want.rgb), 2e-5, 2e-5, "colour");
}

/// `m` with another geometry feature: the density MLP's outputs but the
/// density moved by up to 1.
fn another_geometry_feature(m: &OpenNerf, device: &Device) -> OpenNerf {
    let mut other = m.clone();
    let out = &mut other.fast.as_mut().expect("fast").density_out;
    let [rows, cols] = out.weight.val().dims();
    let step = Tensor::<2>::random(
        [rows, cols - 1],
        burn::tensor::Distribution::Uniform(-1.0, 1.0),
        device,
    );
    let step = Tensor::cat(vec![Tensor::zeros([rows, 1], device), step], 1);
    out.weight = Param::from_tensor(out.weight.val().add(step));
    other
}

/// With `head_reads_geometry` off, the head reads the feature grid alone:
/// its input is the grid's encoding, the features at points stay as they
/// are when the geometry feature changes (they move when the head reads
/// it), and the march renders the features the training pass does.
#[test]
fn a_head_reading_the_feature_grid_alone_ignores_the_geometry_feature() {
    let device = Device::flex();
    device.seed(23);
    let points = Tensor::<2>::random(
        [40, 3],
        burn::tensor::Distribution::Uniform(-2.0, 2.0),
        &device,
    );
    let features = |m: &OpenNerf| vec(m.query_features(points.clone(), 0.01));
    let reads = |geometry: Option<bool>| {
        let mut config = with_feature_grid(fast_config(8, false));
        config.fast = config.fast.map(|f| f.with_head_reads_geometry(geometry));
        config
    };
    let both = varied(&reads(None), &device);
    assert_eq!(both.head.hidden[0].weight.dims(), [7 + 6, 8]);
    let moved = another_geometry_feature(&both, &device);
    assert_ne!(features(&both), features(&moved));

    let m = varied(&reads(Some(false)), &device);
    let fast = m.fast.as_ref().expect("fast");
    assert_eq!((fast.trunk_width(), fast.head_width()), (7 + 6, 6));
    assert_eq!(m.head.hidden[0].weight.dims(), [6, 8]);
    let moved = another_geometry_feature(&m, &device);
    assert_eq!(features(&m), features(&moved));

    assert_the_march_renders_the_training_features(&m, &camera_rays(5, 2));
}

/// The inference pass (the march, without termination) renders what the
/// plain deterministic training pass does, with and without the hash
/// proposal sampler, in every feature mode.
#[test]
fn the_march_renders_what_the_training_pass_does() {
    let off = Termination {
        transmittance: 0.0,
        segment: 5,
    };
    for (name, device) in devices(false) {
        device.seed(9);
        let rays = camera_rays(7, 3);
        for proposal in [false, true] {
            let m = varied(&fast_config(12, proposal), &device);
            for mode in [FeatureMode::None, FeatureMode::Composited] {
                let want = m
                    .render(
                        &RenderRequest::train(&rays)
                            .with_randomized(false)
                            .with_features(mode),
                    )
                    .fine;
                let got = m
                    .render(
                        &RenderRequest::inference(&rays)
                            .with_features(mode)
                            .with_termination(off),
                    )
                    .expect("no observer");
                let what = format!("{name} proposal {proposal} {mode:?}");
                assert_close(&got.rgb, &vec(want.rgb), 2e-5, 2e-5, &what);
                assert_close(&got.depth, &vec(want.depth), 2e-5, 2e-5, &what);
                if let Some(f) = want.feature {
                    assert_close(&got.feature, &vec(f), 2e-5, 2e-5, &what);
                }
            }
        }
    }
}

/// Weights saved and loaded into a field built from the same configuration
/// render the same colours bit for bit.
#[test]
fn weights_round_trip() {
    use burn::store::ModuleRecord;
    use burn::tensor::Bytes;
    let device = Device::flex();
    device.seed(1);
    let config = fast_config(8, true);
    let m = varied(&config, &device);
    let bytes = m.clone().into_record().into_bytes().expect("serialise");
    let record =
        ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes.to_vec())).expect("a burnpack");
    let back = config
        .init(&device)
        .try_load_record(record)
        .expect("weights match");
    let rays = camera_rays(4, 5);
    let render = |m: &OpenNerf| {
        m.render(&RenderRequest::inference(&rays))
            .expect("no observer")
            .rgb
    };
    assert_eq!(render(&m), render(&back));
}

/// A Mip-NeRF field's weights keep their names (`mlp.trunk.0.weight`, in
/// the burnpack's header): runs written before the fast field existed load
/// as they did.
#[test]
fn the_mip_fields_weights_keep_their_names() {
    let device = Device::flex();
    let bytes = common::tiny_config()
        .init(&device)
        .into_record()
        .into_bytes()
        .expect("serialise");
    let holds = |name: &str| bytes.windows(name.len()).any(|w| w == name.as_bytes());
    assert!(holds("mlp.trunk.0.weight") && holds("mlp.rgb.bias"));
    assert!(!holds("fast.") && !holds("Some"));
}

/// A configuration written before the density shift, the footprint
/// weights and the feature grid (a run trained without them) loads with
/// none of them, as it was trained.
#[test]
fn a_configuration_without_the_newer_keys_loads_as_it_was_trained() {
    let mut config = fast_config(8, true);
    config = with_feature_grid(config);
    config.fast = config.fast.map(|f| {
        f.with_density_shift(Some(-1.0))
            .with_footprint_weights(Some(true))
    });
    config.proposal = config.proposal.map(|p| p.with_density_shift(Some(-1.0)));
    let mut old = serde_json::to_value(config).expect("json");
    let fast = old["fast"].as_object_mut().expect("the fast field");
    assert!(fast.remove("density_shift").is_some());
    assert!(fast.remove("footprint_weights").is_some());
    assert!(fast.remove("feature_grid").is_some());
    let proposal = old["proposal"].as_object_mut().expect("the proposal");
    assert!(proposal.remove("density_shift").is_some());
    let loaded: OpenNerfConfig = serde_json::from_value(old).expect("an old configuration");
    let device = Device::flex();
    let m = loaded.init(&device);
    let fast = m.fast.as_ref().expect("the fast field");
    assert_eq!((fast.density_shift, fast.footprint_weights), (0.0, false));
    assert!(fast.feature_grid.is_none());
    let (_, proposal) = m.proposal_sampler().expect("proposal");
    assert_eq!(proposal.density_shift, 0.0);
}
