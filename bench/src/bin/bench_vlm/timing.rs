//! Timing the dense extraction on a Burn backend, and its FLOP count.

use std::time::Instant;

use anyhow::{Context, Result, bail, ensure};
use burn::tensor::{Device, Distribution, Tensor};
use clip::vision::{DenseOptions, VisionModel};
use clip::{ClipVisionConfig, DenseVariant};
use field_ops::backend::{BackendArgs, BackendKind};
use train::backend::vulkan_available;

use super::cpu::timed;
use super::{Args, Geometry, breakdown};

/// Matrix-product FLOPs (2 per multiply-add) of one window through the
/// tower: patch embedding, every block (q, k, v and output projections,
/// the two attention products, the MLP), the last block as `variant` runs
/// it (no MLP; NACLIP and ClearCLIP project two of q/k/v plus the output,
/// MaskCLIP only v and the output, without attention), and the projection
/// of the patch tokens. Element-wise work (norms, softmax, GELU) is not
/// counted.
pub(crate) fn window_flops(c: &ClipVisionConfig, variant: DenseVariant) -> f64 {
    let g = (c.image_size / c.patch_size) as f64;
    let patches = g * g;
    let t = patches + 1.0;
    let w = c.width as f64;
    let mlp = c.mlp_width as f64;
    let attention = 2.0 * 2.0 * t * t * w;
    let block = 2.0 * t * (4.0 * w * w + 2.0 * w * mlp) + attention;
    let last = match variant {
        DenseVariant::Naclip | DenseVariant::Clearclip => 2.0 * t * 3.0 * w * w + attention,
        DenseVariant::Maskclip => 2.0 * t * 2.0 * w * w,
    };
    let embed = 2.0 * patches * (3.0 * (c.patch_size * c.patch_size) as f64) * w;
    let projection = 2.0 * patches * w * c.embed_dim as f64;
    embed + (c.layers as f64 - 1.0) * block + last + projection
}

/// `height x width x 3` random values `k / 255` (`k` a seeded uint8), HWC.
pub(crate) fn random_frame(height: usize, width: usize, seed: u64) -> Vec<f32> {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..height * width * 3)
        .map(|_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 56) as u8) as f32 / 255.0
        })
        .collect()
}

/// The device of `compute`, refused with a reason where it cannot run here.
pub(crate) fn checked_device(compute: BackendArgs) -> Result<Device> {
    compute.check().map_err(anyhow::Error::msg)?;
    let kind = compute.backend;
    if kind == BackendKind::Wgpu && !vulkan_available() {
        bail!(
            "--backend wgpu: no Vulkan driver is installed (no manifest under \
             /usr/share/vulkan/icd.d or /etc/vulkan/icd.d); without one wgpu falls back to \
             OpenGL, which deadlocks on software renderers. Install a GPU driver (or \
             mesa-vulkan-drivers for lavapipe on the CPU), or leave wgpu out of --backend"
        );
    }
    if kind == BackendKind::Wgpu {
        eprintln!(
            "wgpu: the warm-up frame compiles and autotunes kernels (minutes; \
             CUBECL_AUTOTUNE_LEVEL=minimal shortens it); on lavapipe (no GPU) a frame takes minutes"
        );
    }
    Ok(compute.device())
}

/// Seconds per frame of the tower's matrix products alone, at the shapes a
/// frame's batches run them (rows of every batch folded into one 2D
/// product for the linear layers, `[batch, heads]` batched products for
/// attention), with random operands made beforehand.
pub(crate) fn gemm_seconds(
    dev: &Device,
    c: &ClipVisionConfig,
    variant: DenseVariant,
    windows: usize,
    batch: usize,
) -> Result<f64> {
    let g = c.image_size / c.patch_size;
    let t = g * g + 1;
    let (w, mlp, heads) = (c.width, c.mlp_width, c.heads);
    ensure!(
        heads > 0 && w % heads == 0,
        "width {w} is not a multiple of {heads} heads"
    );
    let hd = w / heads;
    let rnd2 = |s: [usize; 2]| Tensor::<2>::random(s, Distribution::Default, dev);
    let rnd4 = |s: [usize; 4]| Tensor::<4>::random(s, Distribution::Default, dev);
    let (sq, up, down) = (rnd2([w, w]), rnd2([w, mlp]), rnd2([mlp, w]));
    let patch_w = rnd2([3 * c.patch_size * c.patch_size, w]);
    let proj = rnd2([w, c.embed_dim]);
    let sizes: Vec<usize> = (0..windows)
        .step_by(batch)
        .map(|s| batch.min(windows - s))
        .collect();
    let mut inputs = Vec::new();
    for &b in &sizes {
        inputs.push((
            rnd2([b * (t - 1), 3 * c.patch_size * c.patch_size]),
            rnd2([b * t, w]),
            rnd2([b * t, mlp]),
            rnd4([b, heads, t, hd]),
            rnd4([b, heads, t, t]),
        ));
    }
    let run = || -> f32 {
        let mut acc = Tensor::<1>::zeros([1], dev);
        for (px, x, hidden, q, a) in &inputs {
            acc = acc + px.clone().matmul(patch_w.clone()).sum();
            for layer in 0..c.layers {
                let last = layer + 1 == c.layers;
                let projections = match (last, variant) {
                    (false, _) => 4,
                    (true, DenseVariant::Maskclip) => 2,
                    (true, _) => 3,
                };
                for _ in 0..projections {
                    acc = acc + x.clone().matmul(sq.clone()).sum();
                }
                if !(last && variant == DenseVariant::Maskclip) {
                    acc = acc + q.clone().matmul(q.clone().swap_dims(2, 3)).sum();
                    acc = acc + a.clone().matmul(q.clone()).sum();
                }
                if !last {
                    acc = acc + x.clone().matmul(up.clone()).sum();
                    acc = acc + hidden.clone().matmul(down.clone()).sum();
                }
            }
            let [rows, _] = x.dims();
            acc = acc
                + x.clone()
                    .slice([0..rows - rows / t, 0..w])
                    .matmul(proj.clone())
                    .sum();
        }
        acc.into_scalar::<f32>()
    };
    let _ = run(); // warm-up
    // The faster of two runs: one run alone varies by 20% on a shared machine.
    let mut best = f64::INFINITY;
    for _ in 0..2 {
        let start = Instant::now();
        let _ = run();
        best = best.min(start.elapsed().as_secs_f64());
    }
    Ok(best)
}

/// What one backend measured.
pub(crate) struct BackendTiming {
    /// Seconds of each timed frame.
    pub(crate) per_frame: Vec<f64>,
    pub(crate) geometry: Geometry,
    /// Seconds per frame of the matrix products alone.
    pub(crate) gemm: Option<f64>,
    /// Cores kept busy over the timed frames.
    pub(crate) cores_busy: Option<f64>,
}

/// Times the Burn extraction on `kind`.
pub(crate) fn time_backend(
    kind: BackendKind,
    args: &Args,
    frame: &[f32],
    options: &DenseOptions,
) -> Result<BackendTiming> {
    let dev = checked_device(args.compute.of(kind))?;
    dev.seed(args.seed);
    let config = ClipVisionConfig::vit_b_16();
    let encoder = config.init(&dev);
    let model = VisionModel::from_encoder(encoder, config.clone(), &dev);
    let (h, w) = (args.height as usize, args.width as usize);
    let plan = model
        .plan((h, w), options)
        .with_context(|| format!("planning the windows of a {w}x{h} frame"))?;
    let geometry = Geometry {
        width: w,
        height: h,
        short_side: args.short_side as usize,
        resized: plan.resized,
        grid: plan.grid,
        windows: plan.origins.len(),
        batch: options.batch,
        dense: options.variant.name().into(),
    };
    let one_frame = |i: u64| -> Result<f64> {
        let start = Instant::now();
        let map = model
            .dense_map(frame, (h, w), options)
            .with_context(|| format!("{kind}: dense map of frame {i}"))?;
        let secs = start.elapsed().as_secs_f64();
        ensure!(
            (map.rows, map.cols) == plan.grid,
            "{kind}: the map is {}x{}, the plan says {:?}",
            map.rows,
            map.cols,
            plan.grid
        );
        ensure!(
            map.data.iter().all(|v| v.is_finite()),
            "{kind}: the dense map has non-finite values"
        );
        Ok(secs)
    };
    eprintln!("{kind}: warm-up frame {:.3} s", one_frame(0)?);
    let (times, _, cores_busy) = timed(|| -> Result<Vec<f64>> {
        let mut times = Vec::new();
        for i in 1..=args.frames {
            let secs = one_frame(i)?;
            eprintln!("{kind}: frame {i} {secs:.3} s");
            times.push(secs);
        }
        Ok(times)
    });
    let times = times?;
    let gemm = if args.no_gemm {
        None
    } else {
        let secs = gemm_seconds(
            &dev,
            &config,
            options.variant,
            geometry.windows,
            options.batch,
        )
        .with_context(|| format!("{kind}: timing the matrix products alone"))?;
        eprintln!("{kind}: matrix products alone {secs:.3} s per frame");
        Some(secs)
    };
    if args.breakdown {
        breakdown::print_stages(kind, &model, frame, (h, w), options)
            .with_context(|| format!("{kind}: per-stage breakdown"))?;
        breakdown::print_operations(kind, &dev, &model, &config, &geometry)
            .with_context(|| format!("{kind}: per-operation breakdown"))?;
    }
    Ok(BackendTiming {
        per_frame: times,
        geometry,
        gemm,
        cores_busy,
    })
}
