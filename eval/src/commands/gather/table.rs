//! The benchmark table: per scene, mean +- standard deviation over its
//! runs; then the mean over scenes (of their means), with the standard
//! deviation across scenes. mIoU and mAcc are in percent, as in the
//! paper's tables.

use std::fmt::Write;

use field_ops::scores::{GroupScore, SegmentationScores};

use super::{RunResult, RunStatus};

/// Mean and sample standard deviation of `n` values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stat {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (n - 1 in the denominator; 0 for one value).
    pub std: f64,
    /// Values.
    pub n: usize,
}

impl Stat {
    /// Of `values`; `None` when empty.
    pub fn of(values: &[f64]) -> Option<Self> {
        let n = values.len();
        if n == 0 {
            return None;
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let var = if n > 1 {
            values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64
        } else {
            0.0
        };
        Some(Self {
            mean,
            std: var.sqrt(),
            n,
        })
    }

    fn cell(v: Option<Self>, digits: usize) -> String {
        match v {
            None => "-".into(),
            Some(s) if s.n == 1 => format!("{:.digits$}", s.mean),
            Some(s) => format!("{:.digits$} ± {:.digits$}", s.mean, s.std),
        }
    }
}

/// The table's columns: held-out PSNR and SSIM, then mIoU and mAcc of each
/// class group.
pub const COLUMNS: [&str; 10] = [
    "psnr",
    "ssim",
    "miou",
    "macc",
    "head_miou",
    "head_macc",
    "common_miou",
    "common_macc",
    "tail_miou",
    "tail_macc",
];

/// A run's value in column `c` of `COLUMNS` (segmentation scores in
/// percent).
fn value(r: &RunResult, c: usize) -> Option<f64> {
    match c {
        0 => return r.psnr,
        1 => return r.ssim,
        _ => {}
    }
    let s: &SegmentationScores = r.scores.as_ref()?;
    let group: Option<&GroupScore> = match (c - 2) / 2 {
        0 => Some(&s.all),
        1 => s.head.as_ref(),
        2 => s.common.as_ref(),
        _ => s.tail.as_ref(),
    };
    let g = group?;
    let v = if c.is_multiple_of(2) { g.miou } else { g.macc };
    v.map(|x| 100.0 * x)
}

/// A runs' table row: a statistic per column.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// One per column of the table: PSNR, SSIM, then mIoU and mAcc of all,
    /// head, common and tail classes.
    pub stats: [Option<Stat>; 10],
}

/// A scene's row.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneRow {
    /// Scene name (`mean` for the mean over scenes).
    pub scene: String,
    /// Runs that count: trained (`summary.json`); the segmentation columns
    /// average those of them that are segmented.
    pub counted: usize,
    /// Runs the scene has in the batch.
    pub total: usize,
    /// Its statistics.
    pub row: Row,
}

/// One row per scene (in the order scenes first appear), then the mean
/// over the scenes that have figures.
pub fn scene_rows(runs: &[RunResult]) -> Vec<SceneRow> {
    let mut scenes: Vec<&str> = Vec::new();
    for r in runs {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    let mut rows: Vec<SceneRow> = scenes
        .iter()
        .map(|scene| {
            let mine: Vec<&RunResult> = runs.iter().filter(|r| r.scene == *scene).collect();
            // A trained run's figures count whatever happened after
            // training (a failed eval step is listed under the table).
            let counted: Vec<&&RunResult> = mine.iter().filter(|r| r.psnr.is_some()).collect();
            let stats = std::array::from_fn(|c| {
                let values: Vec<f64> = counted.iter().filter_map(|r| value(r, c)).collect();
                Stat::of(&values)
            });
            SceneRow {
                scene: scene.to_string(),
                counted: counted.len(),
                total: mine.len(),
                row: Row { stats },
            }
        })
        .collect();
    let stats = std::array::from_fn(|c| {
        let means: Vec<f64> = rows
            .iter()
            .filter_map(|r| r.row.stats[c].map(|s| s.mean))
            .collect();
        Stat::of(&means)
    });
    rows.push(SceneRow {
        scene: "mean".into(),
        counted: rows.iter().filter(|r| r.counted > 0).count(),
        total: rows.len(),
        row: Row { stats },
    });
    rows
}

/// The table in Markdown, with the runs not counted listed below it.
pub fn markdown(rows: &[SceneRow], runs: &[RunResult]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Held-out PSNR (dB) and SSIM (interior pixels; SSIM from runs that rendered their \
         held-out views in full) and 3D segmentation (%), mean ± std over each scene's runs; \
         the last row is the mean over scenes ± std across them.\n"
    );
    let _ = writeln!(
        s,
        "| scene | runs | PSNR | SSIM | mIoU | mAcc | head mIoU | head mAcc | common mIoU | common mAcc | tail mIoU | tail mAcc |"
    );
    let _ = writeln!(s, "|---|---|{}", "---|".repeat(COLUMNS.len()));
    for r in rows {
        let cells: Vec<String> = r
            .row
            .stats
            .iter()
            .enumerate()
            .map(|(c, v)| Stat::cell(*v, [2, 3].get(c).copied().unwrap_or(1)))
            .collect();
        let name = if r.scene == "mean" {
            "**mean**".to_string()
        } else {
            r.scene.clone()
        };
        let _ = writeln!(
            s,
            "| {name} | {}/{} | {} |",
            r.counted,
            r.total,
            cells.join(" | ")
        );
    }
    let missing: Vec<&RunResult> = runs
        .iter()
        .filter(|r| r.status != RunStatus::Finished)
        .collect();
    let finished = runs.len() - missing.len();
    let _ = writeln!(s, "\n{finished} of {} runs finished.", runs.len());
    if !missing.is_empty() {
        let _ = writeln!(s, "\nNot finished or not fully counted:\n");
        for r in missing {
            let _ = writeln!(s, "- {} ({}): {}", r.run, r.scene, r.status.describe());
        }
    }
    s
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn num(v: Option<f64>) -> String {
    v.map(|x| format!("{x:.6}")).unwrap_or_default()
}

/// The scenes' table as CSV: `scene,counted,total` then `<column>_mean`,
/// `<column>_std` per column.
pub fn scenes_csv(rows: &[SceneRow]) -> String {
    let mut s = String::from("scene,counted,total");
    for c in COLUMNS {
        let _ = write!(s, ",{c}_mean,{c}_std");
    }
    s.push('\n');
    for r in rows {
        let _ = write!(s, "{},{},{}", csv_field(&r.scene), r.counted, r.total);
        for st in &r.row.stats {
            let _ = write!(s, ",{},{}", num(st.map(|x| x.mean)), num(st.map(|x| x.std)));
        }
        s.push('\n');
    }
    s
}

/// Every run as CSV: its scene, status and figures.
pub fn runs_csv(runs: &[RunResult]) -> String {
    let mut s = String::from("scene,run,seed,status,iterations");
    for c in COLUMNS {
        let _ = write!(s, ",{c}");
    }
    s.push('\n');
    for r in runs {
        let _ = write!(
            s,
            "{},{},{},{},{}",
            csv_field(&r.scene),
            csv_field(&r.run),
            r.seed.map(|x| x.to_string()).unwrap_or_default(),
            csv_field(&r.status.describe()),
            r.iterations.map(|x| x.to_string()).unwrap_or_default()
        );
        for c in 0..COLUMNS.len() {
            let _ = write!(s, ",{}", num(value(r, c)));
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stat_is_the_sample_mean_and_deviation() {
        let s = Stat::of(&[1.0, 2.0, 4.0]).unwrap();
        assert!((s.mean - 7.0 / 3.0).abs() < 1e-12);
        // Sum of squared deviations 14/3 over n - 1 = 2.
        assert!((s.std - (7.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(Stat::of(&[5.0]).unwrap().std, 0.0);
        assert!(Stat::of(&[]).is_none());
    }

    #[test]
    fn ssim_has_its_column_beside_psnr_in_every_table() {
        let run = |name: &str, psnr: f64, ssim: Option<f64>| RunResult {
            scene: "room".into(),
            run: name.into(),
            seed: None,
            status: RunStatus::NotSegmented,
            iterations: Some(10),
            psnr: Some(psnr),
            ssim,
            scores: None,
        };
        let runs = [
            run("a", 20.0, Some(0.5)),
            run("b", 22.0, Some(0.75)),
            run("old", 21.0, None),
        ];
        let rows = scene_rows(&runs);
        let ssim = rows[0].row.stats[1].unwrap();
        assert_eq!((ssim.mean, ssim.n), (0.625, 2));
        let md = markdown(&rows, &runs);
        assert!(md.contains("| PSNR | SSIM | mIoU |"), "{md}");
        assert!(
            md.contains("| room | 3/3 | 21.00 ± 1.00 | 0.625 ± 0.177 | - |"),
            "{md}"
        );
        let csv = runs_csv(&runs);
        assert!(
            csv.starts_with("scene,run,seed,status,iterations,psnr,ssim,miou,"),
            "{csv}"
        );
        assert!(csv.contains(",20.000000,0.500000,,"), "{csv}");
        assert!(csv.contains(",21.000000,,,"), "{csv}");
        let scenes = scenes_csv(&rows);
        assert!(
            scenes.contains("psnr_mean,psnr_std,ssim_mean,ssim_std,miou_mean"),
            "{scenes}"
        );
    }

    #[test]
    fn csv_quotes_what_needs_quoting() {
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("plain"), "plain");
        assert_eq!(csv_field("say \"x\""), "\"say \"\"x\"\"\"");
        assert_eq!(csv_field("say \"x\", y"), "\"say \"\"x\"\", y\"");
    }
}
