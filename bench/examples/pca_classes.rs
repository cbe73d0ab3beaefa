//! How well a scene's PCA basis keeps the class embeddings themselves.
//!
//!     cargo run --release -p bench --example pca_classes -- 21 22 23
//!
//! The basis is fitted to the extractor's maps (mixtures of classes plus
//! noise), but a novel view read with ground-truth labels writes the pure
//! text embedding of each class into its map, which is then compressed with
//! that basis. Per class this prints the cosine between the embedding and
//! its compressed-and-lifted version, and the class that version is nearest
//! to (cosine over all class embeddings, as `eval segment` scores features).

use datasets::synthetic::{SceneSize, generate};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seeds: Vec<u64> = std::env::args()
        .skip(1)
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    for seed in if seeds.is_empty() { vec![21] } else { seeds } {
        let scene = generate(seed, SceneSize::Bench)?;
        let features = scene.features.as_ref().ok_or("no maps")?;
        let basis = features.pca.as_ref().ok_or("no PCA basis")?;
        let classes = scene.classes.as_ref().ok_or("no classes")?;
        println!(
            "seed {seed}: k = {} of {} ({:.3} of the variance)",
            basis.k, basis.dim, basis.explained_variance_ratio
        );
        let cos = |a: &[f32], b: &[f32]| {
            let dot: f64 = a.iter().zip(b).map(|(x, y)| *x as f64 * *y as f64).sum();
            let na: f64 = a.iter().map(|x| (*x as f64).powi(2)).sum::<f64>().sqrt();
            let nb: f64 = b.iter().map(|x| (*x as f64).powi(2)).sum::<f64>().sqrt();
            dot / (na * nb).max(1e-12)
        };
        let mut wrong = 0;
        for c in 0..classes.len() {
            let e = classes.row(c);
            let back = basis.lift(&basis.project(e));
            let scores: Vec<f64> = (0..classes.len())
                .map(|j| cos(&back, classes.row(j)))
                .collect();
            let best = (0..scores.len())
                .max_by(|&a, &b| scores[a].total_cmp(&scores[b]))
                .unwrap_or(c);
            if best != c {
                wrong += 1;
            }
            println!(
                "  {:<14} kept cos {:.3}  nearest {:<14} ({:.3} vs own {:.3})",
                classes.names[c],
                cos(&back, e),
                classes.names[best],
                scores[best],
                scores[c]
            );
        }
        println!(
            "  {wrong} of {} classes nearest to another class after compression",
            classes.len()
        );
    }
    Ok(())
}
