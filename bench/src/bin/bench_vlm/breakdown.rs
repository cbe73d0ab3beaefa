//! `--breakdown`: where a frame's time goes on one backend. The stages of
//! `dense_map` timed apart, then each operation of one block timed alone at
//! the frame's batch shape, each with the cores it kept busy.

use std::time::Instant;

use anyhow::{Context, Result};
use burn::tensor::activation::{sigmoid, softmax};
use burn::tensor::{Device, Distribution, Tensor};
use clip::ClipVisionConfig;
use clip::tower::ResidualAttentionBlock;
use clip::vision::{DenseOptions, VisionModel};
use train::backend::BackendKind;

use super::Geometry;
use super::cpu::timed;

fn busy(b: Option<f64>) -> String {
    b.map_or("-".into(), |x| format!("{x:.2}"))
}

/// Times the stages of one frame apart, as `dense_map` runs them: resize
/// and normalise, the tower on each batch of windows (crops included), and
/// the averaging of the windows.
pub(crate) fn print_stages(
    kind: BackendKind,
    model: &VisionModel,
    frame: &[f32],
    (h, w): (usize, usize),
    options: &DenseOptions,
) -> Result<()> {
    let plan = model.plan((h, w), options)?;
    let (image, pre_s, pre_busy) = timed(|| model.preprocess(frame, (h, w), &plan));
    let (features, tower_s, tower_busy) = timed(|| model.window_features(&image, &plan, options));
    let features = features?;
    let (_, avg_s, avg_busy) = timed(|| plan.assemble(&features, model.dim()));
    println!("{kind}: one frame's stages");
    println!("  {:<40} {:>9} {:>6}", "stage", "s", "cores");
    let resize = format!(
        "resize {w}x{h} -> {}x{} + normalise",
        plan.resized.1, plan.resized.0
    );
    println!("  {resize:<40} {pre_s:>9.3} {:>6}", busy(pre_busy));
    let tower = format!("tower, {} windows", plan.origins.len());
    println!("  {tower:<40} {tower_s:>9.3} {:>6}", busy(tower_busy));
    println!(
        "  {:<40} {avg_s:>9.3} {:>6}",
        "average the windows",
        busy(avg_busy)
    );
    Ok(())
}

/// An operation of the breakdown: its label, how many times a block runs
/// it (0: a detail, not summed), and the operation (it syncs by reading
/// one value of its output).
type Op<'a> = (String, f64, Box<dyn Fn() -> f32 + 'a>);

/// Times each operation of one full block alone on `[batch, 197, 768]`
/// activations (`batch` the frame's first batch) and prints milliseconds
/// per call, the cores kept busy, and an estimate per frame: calls per
/// block x blocks x windows / batch (every block counted as a full one).
/// Random activations of one block's shapes at batch `b`.
struct Inputs {
    x: Tensor<3>,
    hidden: Tensor<3>,
    q: Tensor<4>,
    probs: Tensor<4>,
    b: usize,
    t: usize,
}

impl Inputs {
    fn new(c: &ClipVisionConfig, b: usize, dev: &Device) -> Self {
        let g = c.image_size / c.patch_size;
        let t = g * g + 1;
        let (w, heads, mlp) = (c.width, c.heads, c.mlp_width);
        let hd = w / heads.max(1);
        let normal = Distribution::Normal(0.0, 1.0);
        Self {
            x: Tensor::<3>::random([b, t, w], normal, dev),
            hidden: Tensor::<3>::random([b, t, mlp], normal, dev),
            q: Tensor::<4>::random([b, heads, t, hd], normal, dev),
            probs: softmax(Tensor::<4>::random([b, heads, t, t], normal, dev), 3),
            b,
            t,
        }
    }
}

fn first(y: Tensor<3>) -> f32 {
    y.slice([0..1, 0..1, 0..1]).into_scalar::<f32>()
}

fn first4(y: Tensor<4>) -> f32 {
    y.slice([0..1, 0..1, 0..1, 0..1]).into_scalar::<f32>()
}

/// The products and element-wise work of the MLP and norms.
fn dense_ops<'a>(
    block: &'a ResidualAttentionBlock,
    inp: &'a Inputs,
    c: &ClipVisionConfig,
) -> Vec<Op<'a>> {
    let attn = &block.attn;
    let (b, t, w, mlp) = (inp.b, inp.t, c.width, c.mlp_width);
    let (x, hidden) = (&inp.x, &inp.hidden);
    vec![
        (
            format!("layer norm [{b},{t},{w}]"),
            2.0,
            Box::new(|| first(block.ln1.forward(x.clone()))),
        ),
        (
            format!("Linear {w}->{w} on [{b},{t},{w}]"),
            4.0,
            Box::new(|| first(attn.q_proj.forward(x.clone()))),
        ),
        (
            format!("  the same as one [{},{w}] matmul", b * t),
            0.0,
            Box::new(move || {
                let y = x
                    .clone()
                    .reshape([b * t, w])
                    .matmul(attn.q_proj.weight.val());
                y.slice([0..1, 0..1]).into_scalar::<f32>()
            }),
        ),
        (
            format!("Linear {w}->{mlp}"),
            1.0,
            Box::new(|| first(block.mlp.fc1.forward(x.clone()))),
        ),
        (
            format!("Linear {mlp}->{w}"),
            1.0,
            Box::new(|| first(block.mlp.fc2.forward(hidden.clone()))),
        ),
        (
            format!("quick GELU [{b},{t},{mlp}], x / (1 + exp(-1.702 x))"),
            1.0,
            Box::new(|| {
                let e = hidden.clone().mul_scalar(-1.702).exp().add_scalar(1.0);
                first(hidden.clone() / e)
            }),
        ),
        (
            "  sigmoid alone".into(),
            0.0,
            Box::new(|| first(sigmoid(hidden.clone()))),
        ),
        (
            "  as x * sigmoid(1.702 x)".into(),
            0.0,
            Box::new(|| first(hidden.clone() * sigmoid(hidden.clone().mul_scalar(1.702)))),
        ),
        (
            "  exp alone".into(),
            0.0,
            Box::new(|| first(hidden.clone().exp())),
        ),
        (
            "  a * b alone".into(),
            0.0,
            Box::new(|| first(hidden.clone() * hidden.clone())),
        ),
    ]
}

/// The attention's own work.
fn attention_ops<'a>(
    block: &'a ResidualAttentionBlock,
    inp: &'a Inputs,
    c: &ClipVisionConfig,
) -> Vec<Op<'a>> {
    let attn = &block.attn;
    let (b, t, w, heads) = (inp.b, inp.t, c.width, c.heads);
    let (x, q, probs) = (&inp.x, &inp.q, &inp.probs);
    vec![
        (
            "split heads + k k^T".into(),
            1.0,
            Box::new(|| {
                let k = attn.split_heads(x.clone());
                first4(k.clone().matmul(k.swap_dims(2, 3)))
            }),
        ),
        (
            format!("softmax [{b},{heads},{t},{t}]"),
            1.0,
            Box::new(|| first4(softmax(probs.clone(), 3))),
        ),
        (
            "probs v + merge heads".into(),
            1.0,
            Box::new(|| first(attn.merge_heads(probs.clone().matmul(q.clone())))),
        ),
        (
            "  merge heads alone (a copy)".into(),
            0.0,
            Box::new(|| first(attn.merge_heads(q.clone()))),
        ),
        (
            format!("residual add [{b},{t},{w}]"),
            2.0,
            Box::new(|| first(x.clone() + x.clone())),
        ),
        (
            "attention module, whole".into(),
            0.0,
            Box::new(|| first(attn.forward(x.clone()))),
        ),
        (
            "MLP module, whole".into(),
            0.0,
            Box::new(|| first(block.mlp.forward(x.clone()))),
        ),
    ]
}

pub(crate) fn print_operations(
    kind: BackendKind,
    dev: &Device,
    model: &VisionModel,
    c: &ClipVisionConfig,
    geo: &Geometry,
) -> Result<()> {
    let block = model
        .encoder
        .blocks
        .first()
        .context("the tower has no blocks")?;
    let b = geo.batch.min(geo.windows).max(1);
    let inp = Inputs::new(c, b, dev);
    let x = &inp.x;
    let mut ops = dense_ops(block, &inp, c);
    ops.extend(attention_ops(block, &inp, c));
    let per_frame = c.layers as f64 * geo.windows as f64 / b as f64;
    println!(
        "{kind}: one block's operations alone at batch {b} (s/frame: ms/call x calls/block x {} \
         blocks x {} windows / {b})",
        c.layers, geo.windows
    );
    println!(
        "  {:<40} {:>9} {:>6} {:>10} {:>9}",
        "operation", "ms/call", "cores", "calls/blk", "s/frame"
    );
    let time_op = |op: &dyn Fn() -> f32| {
        let _ = op(); // warm-up
        // At least half a second, so that the 10-ms CPU clock resolves it.
        let (reps, wall, cores) = timed(|| {
            let start = Instant::now();
            let mut reps = 0u32;
            while reps < 3 || (start.elapsed().as_secs_f64() < 0.5 && reps < 1000) {
                let _ = op();
                reps += 1;
            }
            reps
        });
        (wall / f64::from(reps), cores)
    };
    let mut sum = 0.0;
    for (name, calls, op) in &ops {
        let (per_call, cores) = time_op(op.as_ref());
        let (calls_s, frame_s) = if *calls > 0.0 {
            sum += per_call * calls * per_frame;
            (
                format!("{calls}"),
                format!("{:.3}", per_call * calls * per_frame),
            )
        } else {
            ("-".into(), "-".into())
        };
        println!(
            "  {name:<40} {:>9.2} {:>6} {calls_s:>10} {frame_s:>9}",
            per_call * 1e3,
            busy(cores)
        );
    }
    let whole = || first(block.forward(x.clone()));
    let (per_call, cores) = time_op(&whole);
    println!(
        "  {:<40} {:>9} {:>6} {:>10} {sum:>9.3}",
        "sum of the above", "", "", ""
    );
    println!(
        "  {:<40} {:>9.2} {:>6} {:>10} {:>9.3}",
        "whole block",
        per_call * 1e3,
        busy(cores),
        "1",
        per_call * per_frame
    );
    Ok(())
}
