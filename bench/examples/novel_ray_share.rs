//! What clustering a run's novel views together with its captured frames
//! would do to the feature-balanced sampler: the views' share of the rays
//! against their share of the pixels, and per class the change of the
//! captured frames' own rays.
//!
//!     cargo run --release -p bench --example novel_ray_share -- RUN [RUN...]
//!
//! The sampler gives every feature cluster the same share of rays. Novel
//! views whose maps hold features unlike the captured frames' (pure class
//! embeddings from the ground-truth oracle, say) take clusters of their own,
//! and the capture is re-clustered with the rest. Training therefore draws
//! the views apart, by their pixel share (`train::batch::TrainSampler`);
//! this measures what it avoids.

use datasets::balance::{BalanceConfig, BalancedSampler};
use datasets::sampler::SamplerConfig;
use field_ops::json::read_json;
use field_ops::run_dir::{RunDir, Split, load_run_scene};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    for run in std::env::args().skip(1) {
        let dir = RunDir::new(&run);
        let meta: datasets::SceneMeta = read_json(&dir.scene())?;
        let mut split: Split = read_json(&dir.split())?;
        let scene = load_run_scene(&dir, &meta, &mut split)?;
        let novel: Vec<usize> = (0..scene.frames.len())
            .filter(|&i| scene.frames[i].name.starts_with("novel_"))
            .collect();
        let mut frames = split.train.clone();
        frames.extend(&novel);
        let pixels = |f: &[usize]| -> f64 {
            f.iter()
                .map(|&i| (scene.frames[i].rgb.width * scene.frames[i].rgb.height) as f64)
                .sum()
        };
        let config = SamplerConfig::default();
        let balance = BalanceConfig::of(&config).ok_or("uniform sampler")?;
        let classes = scene.classes.as_ref().map_or(0, |c| c.len());
        // Per class, the share of the captured frames' rays, drawn by a
        // sampler over `frames`.
        let class_shares =
            |frames: &[usize]| -> Result<(Vec<f64>, usize, usize), Box<dyn std::error::Error>> {
                let sampler =
                    BalancedSampler::new(&scene, frames, config.border_margin, &balance, 1)?
                        .ok_or("no feature maps")?;
                let mut counts = vec![0f64; classes + 1];
                let (mut drawn, mut from_novel) = (0usize, 0usize);
                for b in 0..400 {
                    let batch = sampler.batch(&config, 1, &scene, b);
                    drawn += batch.len();
                    for p in &batch.pixels {
                        let f = &scene.frames[p[0] as usize];
                        if novel.binary_search(&(p[0] as usize)).is_ok() {
                            from_novel += 1;
                            continue;
                        }
                        let l = f
                            .labels
                            .as_ref()
                            .map_or(u16::MAX, |l| l[(p[2] * f.rgb.width + p[1]) as usize]);
                        counts[(l as usize).min(classes)] += 1.0;
                    }
                }
                let total: f64 = counts.iter().sum();
                Ok((
                    counts.iter().map(|c| c / total.max(1.0)).collect(),
                    drawn,
                    from_novel,
                ))
            };
        let (before, _, _) = class_shares(&split.train)?;
        let (after, drawn, from_novel) = class_shares(&frames)?;
        if let Some(names) = scene.classes.as_ref().map(|c| &c.names) {
            for (c, name) in names.iter().enumerate() {
                println!(
                    "  {name:<14} captured-ray share {:.2}% -> {:.2}% ({:+.0}%)",
                    100.0 * before[c],
                    100.0 * after[c],
                    100.0 * (after[c] / before[c].max(1e-12) - 1.0)
                );
            }
        }
        println!(
            "{run}: {} novel of {} frames; novel pixels {:.1}%, novel rays {:.1}% ({drawn} drawn)",
            novel.len(),
            frames.len(),
            100.0 * pixels(&novel) / pixels(&frames),
            100.0 * from_novel as f64 / drawn as f64
        );
    }
    Ok(())
}
