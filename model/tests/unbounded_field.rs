//! The unbounded field and the proposal sampler composed in the model:
//! configurations of older runs load as the box field with coarse and fine
//! level, the inference pass renders what the training pass does for every
//! field and sampler, rays reach the contraction's far bound with sorted
//! posts, and the losses move only what they should.

mod common;

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::GradientsParams;
use burn::tensor::{Device, Tensor, TensorData};
use common::{assert_close, camera_rays, devices, tiny_config, vec};
use model::geometry::NormalizedRay;
use model::stepfun::{distortion_loss, interlevel_loss};
use model::{
    FeatureMode, OpenNerf, OpenNerfConfig, ProposalConfig, RenderRequest, Termination,
    UnboundedConfig,
};

/// The flex device's random generator is one for the whole test binary,
/// and the tests run on parallel threads: each test that seeds it holds
/// this lock until it ends, so that its weights are the seed's and no
/// other test draws from the generator in between.
fn seeded() -> std::sync::MutexGuard<'static, ()> {
    static SEEDED: std::sync::Mutex<()> = std::sync::Mutex::new(());
    SEEDED
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The four combinations of field and sampler on the tests' tiny field
/// (proposal rounds of 16 and 8 samples on a 1 x 8 proposal MLP).
fn configs(samples: usize) -> Vec<(&'static str, OpenNerfConfig)> {
    let base = tiny_config().with_num_samples(samples);
    let proposal = ProposalConfig::new()
        .with_samples(vec![16, 8])
        .with_depth(1)
        .with_width(8)
        .with_max_deg(4);
    let unbounded = UnboundedConfig::new(2.0);
    vec![
        ("box coarse-fine", base.clone()),
        (
            "box proposal",
            base.clone().with_proposal(Some(proposal.clone())),
        ),
        (
            "unbounded coarse-fine",
            base.clone().with_unbounded(Some(unbounded.clone())),
        ),
        (
            "unbounded proposal",
            base.with_unbounded(Some(unbounded))
                .with_proposal(Some(proposal)),
        ),
    ]
}

#[test]
fn a_configuration_without_the_new_keys_is_the_box_field_with_two_levels() {
    let (_, full) = configs(8).pop().expect("a configuration");
    let mut json: serde_json::Value = serde_json::to_value(&full).expect("serialises");
    let restored: OpenNerfConfig = serde_json::from_value(json.clone()).expect("round trip");
    let u = restored.unbounded.expect("kept");
    assert_eq!((u.radius, u.near, u.far), (2.0, 0.2, 1e4));
    assert_eq!(restored.proposal.expect("kept").samples, vec![16, 8]);
    let object = json.as_object_mut().expect("an object");
    object.remove("unbounded");
    object.remove("proposal");
    let old: OpenNerfConfig = serde_json::from_value(json).expect("an older run's keys");
    assert!(old.unbounded.is_none() && old.proposal.is_none());
    // Its initial weights draw from the generator the seeded tests use.
    let _seeded = seeded();
    let m = old.init(&Device::flex());
    assert!(m.proposal.is_none() && !m.extent.is_unbounded());
}

/// Without termination the inference pass renders the training pass's
/// deterministic fine level, for every field and sampler, and counts the
/// proposal rounds' samples.
#[test]
fn the_march_is_the_dense_render_for_every_field_and_sampler() {
    let bg = Some([0.3, 0.6, 0.1]);
    for (device_name, device) in devices(false) {
        for (name, config) in configs(8) {
            let _seeded = seeded();
            device.seed(4);
            let m = config.init(&device);
            let rays = camera_rays(7, 5);
            let dense = m.render(
                &RenderRequest::train(&rays)
                    .with_randomized(false)
                    .with_background(bg),
            );
            let marched = m
                .render(
                    &RenderRequest::inference(&rays)
                        .with_background(bg)
                        .with_termination(Termination::off()),
                )
                .expect("no observer");
            let what = format!("{device_name} {name}");
            let want = &dense.fine;
            assert_close(&marched.rgb, &vec(want.rgb.clone()), 2e-5, 2e-5, &what);
            assert_close(&marched.acc, &vec(want.acc.clone()), 2e-5, 2e-5, &what);
            assert_close(&marched.depth, &vec(want.depth.clone()), 2e-4, 2e-5, &what);
            let f = want.feature.clone().expect("composited feature");
            assert_close(&marched.feature, &vec(f), 2e-5, 2e-5, &what);
            let per_ray = if m.proposal.is_some() {
                16 + 8 + 8
            } else {
                2 * 8
            };
            assert_eq!(marched.samples_evaluated, 7 * per_ray, "{what}");
            assert_eq!(
                dense.coarse.is_some(),
                m.proposal.is_none(),
                "{what}: a coarse level without proposals"
            );
            assert_eq!(
                dense.proposals.len(),
                if m.proposal.is_some() { 2 } else { 0 }
            );
        }
    }
}

/// The same weights render alike on every backend, for every field and
/// sampler with the hash encoding: the GPU backends resample the proposal
/// rounds and find the hash corners with tensor ops on the device, the CPU
/// backends on the host (`model::host_work`).
#[test]
fn every_backend_renders_the_same_weights_alike() {
    let hash = model::HashGridConfig::new()
        .with_levels(4)
        .with_log2_table(8)
        .with_max_resolution(64);
    let rays = camera_rays(6, 3);
    for (name, config) in configs(8) {
        let config = config.with_hash(Some(hash.clone()));
        let render = |m: &OpenNerf| {
            let out = m.render(&RenderRequest::train(&rays).with_randomized(false));
            (vec(out.fine.rgb), vec(out.fine.depth))
        };
        // The parameters are drawn from the generator when first used: under
        // the lock, so that no other test's draws come between.
        let (reference, rgb, depth) = {
            let _seeded = seeded();
            Device::flex().seed(6);
            let m = config.init(&Device::flex());
            let (rgb, depth) = render(&m);
            (m, rgb, depth)
        };
        for (device_name, device) in devices(true) {
            let m = reference.clone().fork(&device);
            let (r, d) = render(&m);
            let what = format!("{device_name} {name}");
            assert_close(&r, &rgb, 1e-4, 1e-4, &what);
            assert_close(&d, &depth, 1e-3, 1e-4, &what);
        }
    }
}

/// An unbounded field renders every ray from `near * radius` to
/// `far * radius` normalised units, whatever bounds the ray carries; its
/// posts are sorted in `t` and in `s`, and the proposal rounds' posts cover
/// `s` in [0, 1].
#[test]
fn unbounded_rays_run_from_near_to_far_with_sorted_posts() {
    let device = Device::flex();
    let _seeded = seeded();
    device.seed(9);
    let (_, config) = configs(8).pop().expect("unbounded proposal");
    let m = config.init(&device);
    let mut rays = camera_rays(5, 1);
    // A ray that misses the box (near == far) and one with a short far.
    rays[0].far = rays[0].near;
    rays[1].far = rays[1].near + 0.01;
    let out = m.render(&RenderRequest::train(&rays).with_randomized(true));
    let t = vec(out.fine.t_vals.clone());
    let s = vec(out.fine_s.clone().expect("posts in s"));
    let posts = 9;
    for (i, ray) in rays.iter().enumerate() {
        let d = ray.direction;
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let (near, far) = (0.2 * 2.0 / len, 1e4 * 2.0 / len);
        let row = &t[i * posts..(i + 1) * posts];
        let srow = &s[i * posts..(i + 1) * posts];
        assert!(
            ((row[0] - near) / near).abs() < 1e-5,
            "ray {i} starts at near: {}",
            row[0]
        );
        assert!(
            ((row[posts - 1] - far) / far).abs() < 1e-3,
            "ray {i} ends at far"
        );
        assert!(row.windows(2).all(|w| w[0] <= w[1]), "ray {i}: t sorted");
        assert!(srow.windows(2).all(|w| w[0] <= w[1]), "ray {i}: s sorted");
        for p in &out.proposals {
            let ps = vec(p.s_vals.clone());
            let k = ps.len() / rays.len();
            let prow = &ps[i * k..(i + 1) * k];
            assert!(
                prow[0] == 0.0 && prow[k - 1] == 1.0,
                "ray {i}: proposal spans s"
            );
        }
    }
    assert!(vec(out.fine.rgb).iter().all(|v| v.is_finite()));
}

/// Point queries in an unbounded field are finite and non-negative near
/// the origin and a million units away.
#[test]
fn unbounded_point_queries_are_finite_everywhere() {
    let device = Device::flex();
    let _seeded = seeded();
    device.seed(2);
    let (_, config) = configs(8).remove(2);
    let m = config.init(&device);
    let p = vec![
        0.0f32, 0.0, 0.0, 1e-6, 0.0, 0.0, 1e6, -1e6, 3.0, 0.5, 0.2, -0.1,
    ];
    let points = Tensor::<2>::from_data(TensorData::new(p, [4, 3]), &device);
    let density = vec(m.query_density(points.clone(), 0.01));
    let feature = vec(m.query_features(points, 0.01));
    assert!(density.iter().chain(&feature).all(|v| v.is_finite()));
    assert!(density.iter().all(|&d| d >= 0.0));
}

/// Which parameters of the field have a gradient.
struct HasGrad<'a> {
    grads: &'a GradientsParams,
    ids: Vec<(bool, usize)>,
}

impl ModuleVisitor for HasGrad<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let g = self.grads.get::<D>(param.id);
        let nonzero = g.is_some_and(|g| g.abs().sum().into_scalar::<f32>() > 0.0);
        self.ids.push((nonzero, param.shape().num_elements()));
    }
}

fn with_grad(module: &impl Module, grads: &GradientsParams) -> usize {
    let mut v = HasGrad {
        grads,
        ids: Vec::new(),
    };
    module.visit(&mut v);
    v.ids.iter().filter(|(g, _)| *g).count()
}

/// The interlevel loss trains the proposal MLP and nothing else; the
/// distortion loss moves the NeRF MLP and not the proposal MLP (whose
/// posts are detached).
#[test]
fn the_interlevel_loss_trains_only_the_proposal_mlp() {
    let device = Device::flex().autodiff();
    let _seeded = seeded();
    device.seed(6);
    let (_, config) = configs(8).pop().expect("unbounded proposal");
    let m: OpenNerf = config.init(&device);
    let rays: Vec<NormalizedRay> = camera_rays(12, 4);
    let out = m.render(&RenderRequest::train(&rays).with_features(FeatureMode::None));
    let s = out.fine_s.clone().expect("posts in s");
    let inter = out
        .proposals
        .iter()
        .map(|p| {
            interlevel_loss(
                s.clone(),
                out.fine.weights.clone(),
                p.s_vals.clone(),
                p.weights.clone(),
            )
        })
        .reduce(|a, b| a + b)
        .expect("two rounds");
    assert!(
        inter.clone().into_scalar::<f32>() > 0.0,
        "an untrained proposal misses mass"
    );
    let grads = GradientsParams::from_grads(inter.backward(), &m);
    let proposal = m.proposal.clone().expect("a proposal MLP");
    assert!(with_grad(&proposal, &grads) > 0, "the proposal MLP learns");
    assert_eq!(with_grad(&m.mlp, &grads), 0, "the NeRF MLP does not");
    let out = m.render(&RenderRequest::train(&rays).with_features(FeatureMode::None));
    let dist = distortion_loss(out.fine_s.clone().expect("posts"), out.fine.weights.clone());
    let grads = GradientsParams::from_grads(dist.backward(), &m);
    assert!(
        with_grad(&m.mlp, &grads) > 0,
        "distortion moves the NeRF MLP"
    );
    assert_eq!(with_grad(&proposal, &grads), 0, "and not the proposal MLP");
}

#[test]
fn dilation_shrinks_with_the_samples_before() {
    let c = ProposalConfig::new();
    assert_eq!(c.dilation(0), 0.0025 + 0.5);
    assert_eq!(c.dilation(1), 0.0025 + 0.5 / 64.0);
    assert_eq!(c.dilation(2), 0.0025 + 0.5 / 4096.0);
}

/// With `start_at_box`, a ray that crosses the scene box starts where it
/// enters it, a ray that misses it where it passes closest to the box's
/// centre, and a ray whose entry is nearer than `near` (a camera inside
/// the box) at `near`; without it (`None`, as older runs load, or
/// `Some(false)`) every ray starts at `near`. The coarse level's first post
/// is that start and its last the far bound.
#[test]
fn rays_start_where_they_enter_the_scene_box() {
    let at_box = UnboundedConfig::new(2.0).with_start_at_box(Some(true));
    let len = |r: &NormalizedRay| {
        let d = r.direction;
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    };
    let rays = camera_rays(6, 2);
    for r in &rays {
        let near = 0.2 * 2.0 / len(r);
        assert!(r.far > r.near && r.near > 2.0 * near, "{r:?}");
        assert_eq!(at_box.bound(r).near, r.near);
        assert!((at_box.bound(r).far - 1e4 * 2.0 / len(r)).abs() < 1e-2);
        for plain in [
            UnboundedConfig::new(2.0),
            UnboundedConfig::new(2.0).with_start_at_box(Some(false)),
        ] {
            assert!((plain.bound(r).near - near).abs() < 1e-6);
        }
        // Entering nearer than `near`: from `near`.
        let inside = NormalizedRay { near: 1e-3, ..*r };
        assert!((at_box.bound(&inside).near - near).abs() < 1e-6);
        // Missing the box: from the closest approach to the origin, where
        // the ray is perpendicular to the line to the origin.
        let miss = NormalizedRay {
            origin: [r.origin[0] + 4.0, r.origin[1], r.origin[2]],
            far: r.near,
            ..*r
        };
        let t = at_box.bound(&miss).near;
        let p: Vec<f32> = (0..3)
            .map(|k| miss.origin[k] + t * miss.direction[k])
            .collect();
        let dot: f32 = (0..3).map(|k| p[k] * miss.direction[k]).sum();
        assert!(t > near && dot.abs() < 1e-3 * len(r) * len(r), "{t} {dot}");
        // Pointing away from the box: from `near`.
        let away = NormalizedRay {
            direction: miss.direction.map(|v| -v),
            ..miss
        };
        assert!((at_box.bound(&away).near - near).abs() < 1e-6);
    }
    let device = Device::flex();
    let _seeded = seeded();
    device.seed(5);
    let m = tiny_config()
        .with_num_samples(8)
        .with_unbounded(Some(at_box.clone()))
        .init(&device);
    let out = m.render(&RenderRequest::train(&rays).with_randomized(false));
    let coarse = out.coarse.expect("a coarse level");
    let t = vec(coarse.t_vals.clone());
    for (i, r) in rays.iter().enumerate() {
        let row = &t[i * 9..(i + 1) * 9];
        assert!(
            ((row[0] - r.near) / r.near).abs() < 1e-5,
            "ray {i}: {row:?}"
        );
        assert!(((row[8] - at_box.bound(r).far) / row[8]).abs() < 1e-3);
    }
    // Older runs' configurations have no key and load without it.
    let mut json = serde_json::to_value(&at_box).expect("serialises");
    json.as_object_mut().expect("object").remove("start_at_box");
    let old: UnboundedConfig = serde_json::from_value(json).expect("loads");
    assert_eq!(old.start_at_box, None);
}
