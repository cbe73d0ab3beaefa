//! One training step — render, losses, backward, non-finite guard, Adam —
//! written once for every device (the device is a runtime value), in two
//! forms: guarded (the loss terms are read back and a non-finite step is
//! not applied) and deferred (nothing is read back: the values stay on the
//! device until the training loop checks a run of steps at once, see
//! `training::guard`).

use burn::module::{Module, ModuleVisitor, Param, ParamGroup};
use burn::optim::lr_scheduler::module_lr_scheduler::ModuleLrScheduler;
use burn::optim::{GradientsParams, ModuleOptimizer};
use burn::tensor::Tensor;
use model::exposure::{expose, exposure_penalty};
use model::geometry::NormalizedRay;
use model::stepfun::{distortion_loss, interlevel_loss};
use model::{FeatureMode, GridUse, OpenNerf, RenderOutputs, RenderRequest};

use crate::batch::BatchTensors;
use crate::config::LossConfig;
pub use crate::step_report::{StepReport, StepValues};

/// The loss and its terms as tensors (each `[1]`).
#[derive(Debug, Clone)]
pub struct LossTerms {
    /// The weighted total that is differentiated.
    pub total: Tensor<1>,
    /// Fine colour MSE.
    pub rgb: Tensor<1>,
    /// Coarse colour MSE (zero with the proposal sampler).
    pub coarse_rgb: Tensor<1>,
    /// Fine depth Huber (zero without depth targets).
    pub depth: Tensor<1>,
    /// Fine open-set cosine loss (zero without features).
    pub open: Tensor<1>,
    /// Interlevel loss summed over the proposal rounds (zero without them).
    pub interlevel: Tensor<1>,
    /// Distortion loss of the fine level in `s` (for the box field with
    /// coarse and fine level only with `box_distortion_weight`, in
    /// [`linear_s`]).
    pub distortion: Tensor<1>,
}

/// `L = L_rgb + lambda_open L_open + lambda_depth L_depth + c (L_rgb^c +
/// lambda_depth L_depth^c)` with `c = coarse_weight`: the OpenNeRF training
/// objective (colour MSE, open-set feature cosine loss, depth Huber loss on
/// the fine level, with the proposal sampler its intervals' midpoints
/// counted at no more than `losses.depth_cap` times the target) with the
/// coarse level's colour and depth terms weighted by `c`. Depth only where
/// the target is valid (> 0); features only where the target is non-zero. With the proposal sampler (no coarse level) the
/// interlevel loss of every proposal round is added (averaged over the fine
/// intervals and rays, as Mip-NeRF 360), and wherever the fine level has
/// posts in `s` the distortion loss; elsewhere (the box field) the
/// distortion loss in [`linear_s`] when `box_distortion_weight` asks. Row
/// `i` of `batch` is the target of rendered ray `i` (see
/// [`BatchTensors::select`]).
pub fn losses(out: &RenderOutputs, batch: &BatchTensors, cfg: &LossConfig) -> LossTerms {
    let device = batch.rgb.device();
    let zero = || Tensor::<1>::zeros([1], &device);
    let colour = |pred: Tensor<2>| match batch.rgb_weight.as_ref() {
        Some(w) => model::weighted_rgb_mse(pred, batch.rgb.clone(), w.clone()),
        None => model::rgb_mse(pred, batch.rgb.clone()),
    };
    let rgb = colour(out.fine.rgb.clone());
    let coarse_rgb = match &out.coarse {
        Some(coarse) => colour(coarse.rgb.clone()),
        None => zero(),
    };
    let mut total = rgb.clone() + coarse_rgb.clone().mul_scalar(cfg.coarse_weight);
    let mut depth = zero();
    if let Some((target, weight)) = batch.depth.as_ref()
        && cfg.lambda_depth > 0.0
    {
        let d = |pred: Tensor<2>| {
            model::depth_huber(pred, target.clone(), weight.clone(), cfg.huber_delta)
        };
        // Capped with the proposal sampler alone: it pins its last post at
        // the far end, thousands of units out on an unbounded ray.
        let cap = (!out.proposals.is_empty()).then_some(cfg.depth_cap);
        let level_depth = |level: &model::LevelOutputs| match cap {
            None => level.depth.clone(),
            Some(cap) => model::capped_depth(
                level.weights.clone(),
                level.t_vals.clone(),
                target.clone(),
                cap,
            ),
        };
        depth = d(level_depth(&out.fine));
        total = total + depth.clone().mul_scalar(cfg.lambda_depth);
        if let Some(coarse) = &out.coarse {
            let coarse = d(level_depth(coarse));
            total = total + coarse.mul_scalar(cfg.lambda_depth * cfg.coarse_weight);
        }
        if cfg.depth_window_weight > 0.0 {
            // A ray whose target weighs nothing has no target here either.
            let target = target
                .clone()
                .mask_fill(weight.clone().lower_equal_elem(0.0), 0.0);
            let window = |level: &model::LevelOutputs| {
                model::depth_window(
                    level.t_vals.clone(),
                    level.weights.clone(),
                    target.clone(),
                    cfg.depth_window_width,
                )
            };
            total = total + window(&out.fine).mul_scalar(cfg.depth_window_weight);
            if let Some(coarse) = &out.coarse {
                total =
                    total + window(coarse).mul_scalar(cfg.depth_window_weight * cfg.coarse_weight);
            }
        }
    }
    let mut interlevel = zero();
    let mut distortion = zero();
    if let Some(s) = out.fine_s.as_ref() {
        let intervals = (s.dims()[1] - 1).max(1) as f32;
        for p in &out.proposals {
            let l = interlevel_loss(
                s.clone(),
                out.fine.weights.clone(),
                p.s_vals.clone(),
                p.weights.clone(),
            );
            interlevel = interlevel + l.div_scalar(intervals);
        }
        if !out.proposals.is_empty() {
            total = total + interlevel.clone().mul_scalar(cfg.interlevel_weight);
        }
        if cfg.distortion_weight > 0.0 {
            distortion = distortion_loss(s.clone(), out.fine.weights.clone());
            total = total + distortion.clone().mul_scalar(cfg.distortion_weight);
        }
    } else if cfg.box_distortion_weight > 0.0 {
        let s = linear_s(out.fine.t_vals.clone());
        distortion = distortion_loss(s, out.fine.weights.clone());
        total = total + distortion.clone().mul_scalar(cfg.box_distortion_weight);
    }
    let mut open = zero();
    if let (Some(pred), Some(target)) = (out.fine.feature.as_ref(), batch.feature.as_ref())
        && cfg.lambda_open > 0.0
    {
        open = model::open_set_cosine(
            pred.clone(),
            target.values.clone(),
            target.mask.clone(),
            &target.space,
        );
        total = total + open.clone().mul_scalar(cfg.lambda_open);
    }
    LossTerms {
        total,
        rgb,
        coarse_rgb,
        depth,
        open,
        interlevel,
        distortion,
    }
}

/// Each ray's posts mapped linearly onto `[0, 1]`, from its first post to
/// its last: the box field's `s` for the distortion loss.
///
/// # Shapes
/// - `t_vals`: `[n, posts]`; output the same.
pub fn linear_s(t_vals: Tensor<2>) -> Tensor<2> {
    let [n, posts] = t_vals.dims();
    let first = t_vals.clone().slice([0..n, 0..1]);
    let last = t_vals.clone().slice([0..n, posts - 1..posts]);
    (t_vals - first.clone()) / (last - first).clamp_min(1e-9)
}

/// The rendered colours of `batch`'s rays as their photographs' learned
/// exposure makes them (see `model::exposure`), with each ray's correction
/// `[n, 6]`; the outputs as they are when the model learns no exposure.
pub fn expose_outputs(
    model: &OpenNerf,
    mut out: RenderOutputs,
    batch: &BatchTensors,
) -> (RenderOutputs, Option<Tensor<2>>) {
    let Some(exposure) = model.exposure.as_ref() else {
        return (out, None);
    };
    let correction = exposure.per_ray(&batch.frames);
    out.fine.rgb = expose(out.fine.rgb, correction.clone());
    if let Some(coarse) = out.coarse.as_mut() {
        coarse.rgb = expose(coarse.rgb.clone(), correction.clone());
    }
    (out, Some(correction))
}

/// Scheduled learning rates of one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepRates {
    /// Rate of the MLP (trunk, density, colour).
    pub base: f64,
    /// Rate of the open-set head.
    pub head: f64,
    /// Rate of the pose corrections (when the model learns them).
    pub pose: f64,
}

/// Sums `|g|` over the gradients of every float parameter of a module.
struct GradL1<'a> {
    grads: &'a GradientsParams,
    sum: Option<Tensor<1>>,
}

impl ModuleVisitor for GradL1<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.get::<D>(param.id) {
            let s = g.abs().sum();
            self.sum = Some(match self.sum.take() {
                Some(acc) => acc + s,
                None => s,
            });
        }
    }
}

/// The parameter group of the open-set head (by parameter id, which
/// survives saving and loading).
pub fn head_group(model: &OpenNerf) -> ParamGroup {
    ParamGroup::ids_from_module(model.head.clone())
}

/// The mean over photographs of each correction's squared norm (rotation
/// vector and shift), `[1]`: the penalty that holds the cameras near their
/// given poses.
pub fn pose_penalty(pose: &model::PoseCorrection) -> Tensor<1> {
    let p = pose.params.val();
    let [images, _] = p.dims();
    p.square().sum().div_scalar(images.max(1) as f32)
}

/// How a step renders its batch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepRender {
    /// Colour behind the unoccluded part of each ray (black without one).
    pub background: Option<[f32; 3]>,
    /// How the model's occupancy grid is used.
    pub grid: GridUse,
    /// The fraction of training done, for the proposal sampler's annealing.
    pub progress: f32,
    /// Whether the samples along each ray are jittered (training: yes; off,
    /// a step draws nothing from the device's generator, so that backends
    /// can be compared step for step).
    pub jitter: bool,
}

/// One step: render the batch as `render` says (background, grid use,
/// training progress, jitter), compute the losses
/// on the rays rendered (their colours first corrected by their
/// photographs' learned exposure, with its penalty, when the model has
/// one: [`expose_outputs`]), backpropagate, and — only when the loss and every
/// gradient are finite — apply Adam with the head at its own rate. Returns
/// the (possibly unchanged) model and what was measured. One device read
/// per step.
pub fn train_step(
    model: OpenNerf,
    optim: &mut ModuleOptimizer,
    batch: &BatchTensors,
    render: StepRender,
    cfg: &LossConfig,
    rates: StepRates,
) -> (OpenNerf, StepReport) {
    train_step_regularised(model, optim, batch, None, render, cfg, rates)
}

/// Rays of square patches seen from viewpoints no photograph was taken
/// from (see `datasets::unseen`), row-major, patch after patch.
#[derive(Debug, Clone)]
pub struct UnseenPatches {
    /// `patches * side * side` rays.
    pub rays: Vec<NormalizedRay>,
    /// Rays along each side of a patch.
    pub side: usize,
}

/// [`train_step`] with, when `unseen` is given and
/// `cfg.unseen_depth_weight` is positive, the depth smoothness of the
/// unseen patches' rendered depth (RegNeRF's geometry regulariser,
/// [`model::depth_smoothness`]) added to the loss at that weight. The
/// patches are rendered as the batch is, without features, except that
/// the occupancy grid never drops one of their rays (a ray that crosses
/// no occupied cell is rendered whole), so that every patch stays whole.
pub fn train_step_regularised(
    model: OpenNerf,
    optim: &mut ModuleOptimizer,
    batch: &BatchTensors,
    unseen: Option<&UnseenPatches>,
    render: StepRender,
    cfg: &LossConfig,
    rates: StepRates,
) -> (OpenNerf, StepReport) {
    let (out, smoothness) = render_step(&model, batch, unseen, render, cfg);
    finish_step(model, optim, out, batch, smoothness, cfg, rates)
}

/// [`train_step_regularised`] without a read-back: the update is applied
/// whatever the loss, and the values come back on the device, for the
/// caller to read ([`StepValues::read`]) together with others and to undo
/// the steps from the first non-finite one (the training loop keeps the
/// model and optimiser of its last check for that).
pub fn train_step_deferred(
    model: OpenNerf,
    optim: &mut ModuleOptimizer,
    batch: &BatchTensors,
    unseen: Option<&UnseenPatches>,
    render: StepRender,
    cfg: &LossConfig,
    rates: StepRates,
) -> (OpenNerf, StepValues) {
    let (out, smoothness) = render_step(&model, batch, unseen, render, cfg);
    train_step_from_deferred(model, optim, out, batch, smoothness, cfg, rates)
}

/// The batch rendered for a step, with the unseen patches' weighted depth
/// smoothness when asked for.
fn render_step(
    model: &OpenNerf,
    batch: &BatchTensors,
    unseen: Option<&UnseenPatches>,
    render: StepRender,
    cfg: &LossConfig,
) -> (RenderOutputs, Option<Tensor<1>>) {
    let mode = if batch.feature.is_some() && cfg.lambda_open > 0.0 {
        FeatureMode::Composited
    } else {
        FeatureMode::None
    };
    let request = RenderRequest::train(&batch.rays)
        .with_randomized(render.jitter)
        .with_features(mode)
        .with_background(render.background)
        .with_grid(render.grid)
        .with_progress(render.progress);
    let out = if model.pose.is_some() || model.appearance.is_some() {
        let photographs = model::PerPhotograph {
            pose_correction: model.pose.as_ref().map(|p| p.per_ray(&batch.frames)),
            appearance: model.appearance.as_ref().map(|a| a.per_ray(&batch.frames)),
        };
        model.render_train_with(&request, photographs)
    } else {
        model.render(&request)
    };
    let smoothness = unseen
        .filter(|u| cfg.unseen_depth_weight > 0.0 && !u.rays.is_empty())
        .and_then(|u| {
            let grid = match render.grid {
                GridUse::Model => GridUse::KeepEmpty,
                other => other,
            };
            let request = RenderRequest::train(&u.rays)
                .with_randomized(render.jitter)
                .with_features(FeatureMode::None)
                .with_background(render.background)
                .with_grid(grid)
                .with_progress(render.progress);
            let patches = model.render(&request);
            // Rows of a patch must be its rays, in order.
            if patches.kept.is_some() {
                return None;
            }
            let depth = patches.fine.depth;
            Some(model::depth_smoothness(depth, u.side).mul_scalar(cfg.unseen_depth_weight))
        });
    (out, smoothness)
}

/// [`train_step`] for outputs already rendered from `batch.rays` (e.g. with
/// another feature path); the targets of the rays the render kept
/// ([`RenderOutputs::kept`]) are selected here.
pub fn train_step_from(
    model: OpenNerf,
    optim: &mut ModuleOptimizer,
    out: RenderOutputs,
    batch: &BatchTensors,
    cfg: &LossConfig,
    rates: StepRates,
) -> (OpenNerf, StepReport) {
    finish_step(model, optim, out, batch, None, cfg, rates)
}

/// [`train_step_from`] with `extra` (a weighted regulariser, `[1]`) added
/// to the loss: the guarded form, one read-back.
fn finish_step(
    model: OpenNerf,
    optim: &mut ModuleOptimizer,
    out: RenderOutputs,
    batch: &BatchTensors,
    extra: Option<Tensor<1>>,
    cfg: &LossConfig,
    rates: StepRates,
) -> (OpenNerf, StepReport) {
    let (grads, values) = backward(&model, out, batch, extra, cfg);
    let mut report = values.read();
    if !report.finite() {
        return (model, report);
    }
    let model = apply(model, optim, grads, rates);
    report.applied = true;
    (model, report)
}

/// [`train_step_from`] without a read-back (see [`train_step_deferred`]),
/// with `extra` added to the loss.
pub fn train_step_from_deferred(
    model: OpenNerf,
    optim: &mut ModuleOptimizer,
    out: RenderOutputs,
    batch: &BatchTensors,
    extra: Option<Tensor<1>>,
    cfg: &LossConfig,
    rates: StepRates,
) -> (OpenNerf, StepValues) {
    let (grads, values) = backward(&model, out, batch, extra, cfg);
    (apply(model, optim, grads, rates), values)
}

/// The losses of `out` against `batch` (the rows the render kept), their
/// gradients, and the values a step reports, on the device.
fn backward(
    model: &OpenNerf,
    out: RenderOutputs,
    batch: &BatchTensors,
    extra: Option<Tensor<1>>,
    cfg: &LossConfig,
) -> (GradientsParams, StepValues) {
    let kept;
    let batch = match &out.kept {
        Some(rows) => {
            kept = batch.select(rows);
            &kept
        }
        None => batch,
    };
    let clip = out.clip;
    let (out, correction) = expose_outputs(model, out, batch);
    let mut terms = losses(&out, batch, cfg);
    if let Some(c) = correction
        && cfg.exposure_penalty > 0.0
    {
        terms.total = terms.total + exposure_penalty(c).mul_scalar(cfg.exposure_penalty);
    }
    if let Some(pose) = model.pose.as_ref()
        && cfg.pose_penalty > 0.0
    {
        terms.total = terms.total + pose_penalty(pose).mul_scalar(cfg.pose_penalty);
    }
    if let Some(codes) = model.appearance.as_ref()
        && cfg.appearance_penalty > 0.0
    {
        terms.total = terms.total + codes.penalty().mul_scalar(cfg.appearance_penalty);
    }
    if let Some(extra) = extra {
        terms.total = terms.total + extra;
    }
    let grads = terms.total.backward();
    let grads = GradientsParams::from_grads(grads, model);
    let mut visitor = GradL1 {
        grads: &grads,
        sum: None,
    };
    model.visit(&mut visitor);
    let device = terms.total.device();
    let grad_l1 = visitor
        .sum
        .unwrap_or_else(|| Tensor::zeros([1], &device))
        .inner();
    let values = StepValues::new(
        [
            terms.total.inner(),
            terms.rgb.inner(),
            terms.depth.inner(),
            terms.open.inner(),
            grad_l1,
        ],
        clip,
    );
    (grads, values)
}

/// Adam's update with the head (and the pose corrections) at their own
/// rates.
fn apply(
    model: OpenNerf,
    optim: &mut ModuleOptimizer,
    grads: GradientsParams,
    rates: StepRates,
) -> OpenNerf {
    let mut scheduler =
        ModuleLrScheduler::new(rates.base).with_group(head_group(&model), rates.head);
    if let Some(pose) = model.pose.as_ref() {
        scheduler = scheduler.with_group(ParamGroup::ids_from_module(pose.clone()), rates.pose);
    }
    let lr = scheduler.step();
    optim.step(lr, model, grads)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::batch::FeatureTargets;
    use burn::optim::AdamConfig;
    use burn::tensor::{Device, TensorData};
    use model::geometry::NormalizedRay;
    use model::{FeatureHeadConfig, MipMlpConfig, OpenNerfConfig};

    const PLAIN: StepRender = StepRender {
        background: None,
        grid: GridUse::Model,
        progress: 1.0,
        jitter: true,
    };

    fn tiny_config() -> OpenNerfConfig {
        OpenNerfConfig::new(FeatureHeadConfig::new(4).with_width(8))
            .with_mlp(
                MipMlpConfig::new()
                    .with_width(16)
                    .with_depth(2)
                    .with_skip_layer(1)
                    .with_max_deg(4),
            )
            .with_num_samples(8)
    }

    fn tiny_model(device: &Device) -> OpenNerf {
        device.seed(3);
        tiny_config().init(device)
    }

    fn batch(device: &Device, rgb: f32) -> BatchTensors {
        let n = 16;
        let rays: Vec<NormalizedRay> = (0..n)
            .map(|i| NormalizedRay {
                origin: [0.1 * i as f32 - 0.8, 0.0, -2.0],
                direction: [0.0, 0.05, 1.0],
                radius: 0.01,
                near: 0.5,
                far: 3.5,
            })
            .collect();
        let t = |v: Vec<f32>, c: usize| Tensor::<2>::from_data(TensorData::new(v, [n, c]), device);
        BatchTensors {
            rays,
            frames: vec![0; n],
            rgb: t(vec![rgb; n * 3], 3),
            rgb_weight: None,
            depth: Some((t(vec![2.0; n], 1), t(vec![1.0; n], 1))),
            feature: Some(FeatureTargets::dense(t(
                (0..n * 4).map(|i| (i % 3) as f32 - 1.0).collect(),
                4,
            ))),
        }
    }

    /// Parameter values of a module, flattened in visiting order.
    fn values(m: &impl Module) -> Vec<Vec<f32>> {
        struct V(Vec<Vec<f32>>);
        impl ModuleVisitor for V {
            fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
                self.0
                    .push(p.val().into_data().try_to_vec::<f32>().unwrap());
            }
        }
        let mut v = V(Vec::new());
        m.visit(&mut v);
        v.0
    }

    fn mean_abs_change(a: &[Vec<f32>], b: &[Vec<f32>]) -> f64 {
        let (mut s, mut n) = (0.0, 0usize);
        for (x, y) in a.iter().zip(b) {
            for (p, q) in x.iter().zip(y) {
                s += (p - q).abs() as f64;
                n += 1;
            }
        }
        s / n.max(1) as f64
    }

    #[test]
    fn non_finite_targets_leave_model_and_optimiser_untouched() {
        let device = Device::flex().autodiff();
        let model = tiny_model(&device);
        let before = values(&model);
        let mut optim = AdamConfig::new().init();
        let rates = StepRates {
            base: 1e-2,
            head: 1e-2,
            pose: 1e-2,
        };
        let cfg = LossConfig::default();
        let (model, report) = train_step(
            model,
            &mut optim,
            &batch(&device, f32::NAN),
            PLAIN,
            &cfg,
            rates,
        );
        assert!(!report.applied);
        assert!(report.loss.is_nan());
        assert_eq!(values(&model), before);
        let record = format!("{:?}", optim.to_record());
        assert!(
            record.contains("num_tensors: 0"),
            "no optimiser state may be created: {record}"
        );
        let (model, report) =
            train_step(model, &mut optim, &batch(&device, 0.5), PLAIN, &cfg, rates);
        assert!(report.applied && report.loss.is_finite() && report.grad_l1 > 0.0);
        assert_ne!(values(&model), before);
    }

    #[test]
    fn the_head_trains_at_its_own_rate() {
        // Adam's first step moves every parameter with a non-zero gradient
        // by about the learning rate, so the mean change measures the rate.
        let device = Device::flex().autodiff();
        let model = tiny_model(&device);
        let (mlp0, head0) = (values(&model.mlp), values(&model.head));
        let mut optim = AdamConfig::new().with_epsilon(1e-12).init();
        let rates = StepRates {
            base: 1e-4,
            head: 1e-2,
            pose: 1e-2,
        };
        let (model, report) = train_step(
            model,
            &mut optim,
            &batch(&device, 0.5),
            PLAIN,
            &LossConfig::default(),
            rates,
        );
        assert!(report.applied);
        let dm = mean_abs_change(&mlp0, &values(&model.mlp));
        let dh = mean_abs_change(&head0, &values(&model.head));
        assert!(dm > 0.3e-4 && dm <= 1.01e-4, "mlp change {dm}");
        assert!(dh > 0.3e-2 && dh <= 1.01e-2, "head change {dh}");
    }

    #[test]
    fn loss_is_the_weighted_sum_of_its_terms() {
        let device = Device::flex();
        let model = tiny_model(&device);
        let b = batch(&device, 0.3);
        let out = model.render(&RenderRequest::train(&b.rays).with_randomized(false));
        let cfg = LossConfig {
            lambda_open: 0.7,
            lambda_depth: 0.2,
            coarse_weight: 0.1,
            huber_delta: 0.2,
            ..LossConfig::default()
        };
        let t = losses(&out, &b, &cfg);
        let s = |x: Tensor<1>| x.into_scalar::<f32>() as f64;
        // Each level's depth term is the Huber loss of its expected depth
        // (the coarse and fine levels' depth is not capped).
        let level_depth = |l: &model::LevelOutputs| {
            let (target, weight) = b.depth.clone().unwrap();
            s(model::depth_huber(l.depth.clone(), target, weight, 0.2))
        };
        let coarse_depth = level_depth(out.coarse.as_ref().unwrap());
        assert!((s(t.depth.clone()) - level_depth(&out.fine)).abs() < 1e-7);
        let expected = s(t.rgb.clone())
            + 0.1 * s(t.coarse_rgb.clone())
            + 0.7 * s(t.open.clone())
            + 0.2 * s(t.depth.clone())
            + 0.02 * coarse_depth;
        assert!((s(t.total.clone()) - expected).abs() < 1e-5 * expected.max(1.0));
        assert!(s(t.open) > 0.0);
        // The depth window adds its weight times the fine level's term and
        // the coarse weight times the coarse level's.
        let windowed = losses(
            &out,
            &b,
            &LossConfig {
                depth_window_weight: 0.5,
                ..cfg
            },
        );
        let (target, _) = b.depth.clone().unwrap();
        let window = |l: &model::LevelOutputs| {
            s(model::depth_window(
                l.t_vals.clone(),
                l.weights.clone(),
                target.clone(),
                cfg.depth_window_width,
            ))
        };
        let want = 0.5 * window(&out.fine) + 0.05 * window(out.coarse.as_ref().unwrap());
        assert!(want > 1e-3, "{want}");
        let added = s(windowed.total) - s(t.total);
        assert!((added - want).abs() < 1e-5, "{added} vs {want}");
    }

    /// With the proposal sampler and a target nearer than half the ray's far
    /// end, the depth term is the Huber loss of the capped depth, below that
    /// of the plain expected depth: the weight past twice the target (the
    /// default `losses.depth_cap`) counts as if it were there. With the
    /// coarse and fine levels it is the plain one's, whatever the cap.
    #[test]
    fn the_depth_term_counts_far_weight_at_twice_the_target() {
        let device = Device::flex();
        device.seed(3);
        let proposal = tiny_config()
            .with_proposal(Some(
                model::ProposalConfig::new()
                    .with_samples(vec![8])
                    .with_depth(1)
                    .with_width(8)
                    .with_max_deg(4),
            ))
            .init(&device);
        let mut b = batch(&device, 0.3);
        let n = b.rays.len();
        // The rays run from 0.5 to 3.5: past 2.0 the cap binds.
        b.depth = Some((
            Tensor::full([n, 1], 1.0, &device),
            Tensor::ones([n, 1], &device),
        ));
        let cfg = LossConfig {
            lambda_depth: 0.2,
            huber_delta: 0.2,
            ..LossConfig::default()
        };
        let s = |x: Tensor<1>| x.into_scalar::<f32>() as f64;
        let (target, weight) = b.depth.clone().unwrap();
        let huber = |pred: Tensor<2>| {
            s(model::depth_huber(
                pred,
                target.clone(),
                weight.clone(),
                0.2,
            ))
        };
        let out = proposal.render(&RenderRequest::train(&b.rays).with_randomized(false));
        assert!(!out.proposals.is_empty() && out.coarse.is_none());
        let t = losses(&out, &b, &cfg);
        let capped_at = |cap: f32| {
            huber(model::capped_depth(
                out.fine.weights.clone(),
                out.fine.t_vals.clone(),
                target.clone(),
                cap,
            ))
        };
        assert_eq!(cfg.depth_cap, 2.0, "the default cap");
        let capped = capped_at(2.0);
        let plain = huber(out.fine.depth.clone());
        assert!((s(t.depth) - capped).abs() < 1e-7, "{capped}");
        assert!(plain > capped + 1e-3, "plain {plain}, capped {capped}");
        // `losses.depth_cap` moves the cap: at 3 it binds past 3.0 only,
        // so the term lies between the one capped at 2 and the plain one.
        let wider = LossConfig {
            depth_cap: 3.0,
            ..cfg
        };
        let at_three = capped_at(3.0);
        let t3 = s(losses(&out, &b, &wider).depth);
        assert!((t3 - at_three).abs() < 1e-7, "{t3} against {at_three}");
        assert!(
            capped + 1e-4 < at_three && at_three + 1e-4 < plain,
            "capped at 2 {capped}, at 3 {at_three}, plain {plain}"
        );

        // The coarse and fine levels: the plain expected depth, though the
        // cap would bind on their far weight too.
        let coarse_fine = tiny_model(&device);
        let out = coarse_fine.render(&RenderRequest::train(&b.rays).with_randomized(false));
        let t = s(losses(&out, &b, &cfg).depth);
        let plain = huber(out.fine.depth.clone());
        let capped = huber(model::capped_depth(
            out.fine.weights.clone(),
            out.fine.t_vals.clone(),
            target.clone(),
            2.0,
        ));
        assert!((t - plain).abs() < 1e-7, "{t} against the plain {plain}");
        assert!(plain > capped + 1e-3, "plain {plain}, capped {capped}");
    }

    /// The box field's distortion term: off by default; with a weight, the
    /// double integral of the fine weights over the posts mapped onto
    /// `[0, 1]`, against a float64 brute-force sum, added to the total.
    #[test]
    fn box_distortion_is_the_double_integral_over_linear_s() {
        let device = Device::flex();
        let model = tiny_model(&device);
        let b = batch(&device, 0.3);
        let out = model.render(&RenderRequest::train(&b.rays).with_randomized(false));
        let s = |x: Tensor<1>| x.into_scalar::<f32>() as f64;
        let plain = losses(&out, &b, &LossConfig::default());
        assert_eq!(s(plain.distortion.clone()), 0.0);
        let cfg = LossConfig {
            box_distortion_weight: 0.5,
            ..LossConfig::default()
        };
        let t = losses(&out, &b, &cfg);
        let host = |x: Tensor<2>| x.into_data().try_to_vec::<f32>().expect("f32");
        let (posts, weights) = (
            host(out.fine.t_vals.clone()),
            host(out.fine.weights.clone()),
        );
        let [n, p] = out.fine.t_vals.dims();
        let mut expected = 0f64;
        for r in 0..n {
            let t = &posts[r * p..(r + 1) * p];
            let w = &weights[r * (p - 1)..(r + 1) * (p - 1)];
            let s: Vec<f64> = t
                .iter()
                .map(|&v| (v as f64 - t[0] as f64) / (t[p - 1] as f64 - t[0] as f64))
                .collect();
            for i in 0..p - 1 {
                let ui = 0.5 * (s[i] + s[i + 1]);
                for j in 0..p - 1 {
                    let uj = 0.5 * (s[j] + s[j + 1]);
                    expected += w[i] as f64 * w[j] as f64 * (ui - uj).abs();
                }
                expected += (w[i] as f64).powi(2) * (s[i + 1] - s[i]) / 3.0;
            }
        }
        expected /= n as f64;
        let got = s(t.distortion.clone());
        assert!(expected > 1e-4, "{expected}");
        assert!(
            (got - expected).abs() < 1e-5 * expected.max(1e-3),
            "{got} vs {expected}"
        );
        let added = s(t.total) - s(plain.total);
        assert!(
            (added - 0.5 * expected).abs() < 1e-5,
            "{added} vs {expected}"
        );
    }

    #[test]
    fn colour_weights_scale_each_ray_against_a_float64_sum() {
        let device = Device::flex();
        let model = tiny_model(&device);
        let mut b = batch(&device, 0.3);
        let out = model.render(&RenderRequest::train(&b.rays).with_randomized(false));
        let cfg = LossConfig::default();
        let s = |x: Tensor<1>| x.into_scalar::<f32>() as f64;
        let plain = s(losses(&out, &b, &cfg).rgb);
        let n = 16;
        let w: Vec<f32> = (0..n).map(|i| if i < 4 { 0.0 } else { 0.5 }).collect();
        b.rgb_weight = Some(Tensor::<2>::from_data(
            TensorData::new(w.clone(), [n, 1]),
            &device,
        ));
        let weighted = s(losses(&out, &b, &cfg).rgb);
        let pred: Vec<f32> = out
            .fine
            .rgb
            .clone()
            .into_data()
            .try_to_vec::<f32>()
            .expect("rgb");
        let mut sum = 0f64;
        for (i, p) in pred.iter().enumerate() {
            sum += w[i / 3] as f64 * (*p as f64 - 0.3).powi(2);
        }
        let expected = sum / (3 * n) as f64;
        assert!(
            (weighted - expected).abs() < 1e-6 * expected.max(1e-3),
            "{weighted} vs {expected}"
        );
        assert!(weighted < 0.5 * plain, "{weighted} vs {plain}");
        b.rgb_weight = Some(Tensor::<2>::ones([n, 1], &device));
        assert!((s(losses(&out, &b, &cfg).rgb) - plain).abs() < 1e-7);
    }
}
