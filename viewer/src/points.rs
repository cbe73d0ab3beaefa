//! The points the page shows: the scene's labelled cloud, else the
//! capture's sparse points, else points back-projected from depth the field
//! renders at the training cameras; their uncertainty where `eval
//! uncertainty` ran; and the binary layout they travel in.

use std::collections::HashMap;
use std::path::Path;

use datasets::Scene;
use model::OpenNerf;
use model::geometry::{Camera, SceneBox, Vec3};

use field_ops::OpsError;
use field_ops::render::{ViewSettings, render_view};

/// "No class" in the predicted and ground-truth arrays.
pub const NO_CLASS: u16 = u16::MAX;

/// Where the points came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointSource {
    /// The scene's point cloud with ground-truth labels.
    Labelled,
    /// The scene's point cloud without labels (e.g. COLMAP's sparse points).
    Sparse,
    /// Back-projected from depth rendered at the training cameras.
    RenderedDepth,
}

impl PointSource {
    /// The name the API reports.
    pub fn name(self) -> &'static str {
        match self {
            PointSource::Labelled => "labelled cloud",
            PointSource::Sparse => "sparse points",
            PointSource::RenderedDepth => "rendered depth",
        }
    }
}

/// Points with what the page colours them by (all vectors of one length).
#[derive(Debug, Clone, PartialEq)]
pub struct PointSet {
    /// Positions in the scene's frame, metres.
    pub positions: Vec<Vec3>,
    /// Captured colour (grey where the cloud has none).
    pub colours: Vec<[u8; 3]>,
    /// Ground-truth class ([`NO_CLASS`] where unknown).
    pub truth: Vec<u16>,
    /// Uncertainty in `[0, 1]` (NaN where none was computed).
    pub uncertainty: Vec<f32>,
    /// Where the points came from.
    pub source: PointSource,
}

impl PointSet {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Whether any point has a ground-truth class.
    pub fn has_truth(&self) -> bool {
        self.truth.iter().any(|&t| t != NO_CLASS)
    }

    /// Whether any point has an uncertainty.
    pub fn has_uncertainty(&self) -> bool {
        self.uncertainty.iter().any(|u| u.is_finite())
    }

    /// Every `step`-th point, so that at most `max` remain.
    pub fn thinned(self, max: usize) -> Self {
        let step = self.len().div_ceil(max.max(1)).max(1);
        if step == 1 {
            return self;
        }
        let keep = |i: &usize| i.is_multiple_of(step);
        Self {
            positions: every(&self.positions, keep),
            colours: every(&self.colours, keep),
            truth: every(&self.truth, keep),
            uncertainty: every(&self.uncertainty, keep),
            source: self.source,
        }
    }
}

fn every<T: Copy>(v: &[T], keep: impl Fn(&usize) -> bool) -> Vec<T> {
    v.iter()
        .enumerate()
        .filter(|(i, _)| keep(i))
        .map(|(_, x)| *x)
        .collect()
}

/// The scene's own cloud (labels index its `classes` classes; others are
/// [`NO_CLASS`]), or `None` when the scene has none.
pub fn from_scene(scene: &Scene, classes: usize) -> Option<PointSet> {
    let cloud = scene.points.as_ref().filter(|c| !c.positions.is_empty())?;
    let n = cloud.positions.len();
    let truth: Vec<u16> = match &cloud.labels {
        Some(l) => l
            .iter()
            .map(|&l| {
                if (0..classes as i64).contains(&l) {
                    l as u16
                } else {
                    NO_CLASS
                }
            })
            .collect(),
        None => vec![NO_CLASS; n],
    };
    let labelled = truth.iter().any(|&t| t != NO_CLASS);
    Some(PointSet {
        positions: cloud.positions.clone(),
        colours: cloud.colors.clone().unwrap_or_else(|| vec![[150; 3]; n]),
        truth,
        uncertainty: vec![f32::NAN; n],
        source: if labelled {
            PointSource::Labelled
        } else {
            PointSource::Sparse
        },
    })
}

/// Points where the field's rendered opacity is high (above 0.5), from up
/// to `views` of `cameras` (evenly spaced) rendered at `width` pixels wide,
/// with their rendered colours.
pub fn from_rendered_depth(
    model: &OpenNerf,
    cameras: &[Camera],
    scene_box: &SceneBox,
    background: Option<[f32; 3]>,
    (views, width): (usize, u32),
) -> PointSet {
    let step = cameras.len().div_ceil(views.max(1)).max(1);
    let mut set = PointSet {
        positions: Vec::new(),
        colours: Vec::new(),
        truth: Vec::new(),
        uncertainty: Vec::new(),
        source: PointSource::RenderedDepth,
    };
    for cam in cameras.iter().step_by(step) {
        let w = width.min(cam.intrinsics.width).max(1);
        let h = ((cam.intrinsics.height as f64 * w as f64 / cam.intrinsics.width as f64).round()
            as u32)
            .max(1);
        let c = cam.scaled(w, h);
        let settings = ViewSettings::new(background, 4096);
        let v = render_view(model, &c, scene_box, &settings)
            .expect("never cancelled without an observer");
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if v.acc[i] < 0.5 || !v.depth[i].is_finite() || v.depth[i] <= 0.0 {
                    continue;
                }
                let ray = c.ray(x as f64, y as f64);
                // `depth` is z-depth: the ray reaches it at depth / d_z.
                let r = &c.pose.rotation;
                let dz: f64 = (0..3).map(|k| r[k][2] * ray.direction[k]).sum();
                if dz <= 1e-6 {
                    continue;
                }
                let t = v.depth[i] as f64 / dz;
                set.positions.push(std::array::from_fn(|k| {
                    ray.origin[k] + t * ray.direction[k]
                }));
                set.colours.push(std::array::from_fn(|k| {
                    (v.rgb[3 * i + k].clamp(0.0, 1.0) * 255.0).round() as u8
                }));
            }
        }
    }
    let n = set.positions.len();
    set.truth = vec![NO_CLASS; n];
    set.uncertainty = vec![f32::NAN; n];
    set
}

/// Takes the uncertainty of `eval uncertainty`'s CSV (`x,y,z,views,
/// log_det,uncertainty,...`, in the scene's frame) onto the points: each
/// point gets the value of the nearest CSV point within `radius` metres.
/// Returns how many points got one.
pub fn attach_uncertainty(set: &mut PointSet, csv: &Path, radius: f64) -> Result<usize, OpsError> {
    let text = std::fs::read_to_string(csv).map_err(|e| OpsError::io(csv, e))?;
    let mut grid: HashMap<[i64; 3], Vec<(Vec3, f32)>> = HashMap::new();
    let cell = |p: &Vec3| p.map(|x| (x / radius).floor() as i64);
    for (line_no, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let bad = || {
            OpsError::Invalid(format!(
                "{}: line {}: expected x,y,z,views,log_det,uncertainty,...",
                csv.display(),
                line_no + 1
            ))
        };
        if f.len() < 6 {
            return Err(bad());
        }
        let num = |s: &str| s.trim().parse::<f64>().map_err(|_| bad());
        let p = [num(f[0])?, num(f[1])?, num(f[2])?];
        let u = num(f[5])? as f32;
        if p.iter().all(|x| x.is_finite()) {
            grid.entry(cell(&p)).or_default().push((p, u));
        }
    }
    let mut matched = 0;
    for (i, p) in set.positions.iter().enumerate() {
        let c = cell(p);
        let mut best = (radius * radius, f32::NAN);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let key = [c[0] + dx, c[1] + dy, c[2] + dz];
                    for (q, u) in grid.get(&key).into_iter().flatten() {
                        let d: f64 = (0..3).map(|k| (p[k] - q[k]).powi(2)).sum();
                        if d <= best.0 {
                            best = (d, *u);
                        }
                    }
                }
            }
        }
        if best.1.is_finite() {
            matched += 1;
        }
        set.uncertainty[i] = best.1;
    }
    Ok(matched)
}

/// Bytes of the `/api/points` layout (little-endian): `"ONPT"`, format 1,
/// `n`, the field version, then `f32[3n]` positions, `u8[4n]` RGBA
/// colours, `u16[n]` predicted classes, `u16[n]` ground truth and `f32[n]`
/// uncertainty: `16 + 24 n` bytes, every array aligned to its element size.
pub fn encode(set: &PointSet, predicted: &[u16], field_version: u64) -> Vec<u8> {
    let n = set.len();
    let mut out = Vec::with_capacity(16 + 24 * n);
    out.extend_from_slice(b"ONPT");
    out.extend_from_slice(&1u32.to_le_bytes());
    out.extend_from_slice(&(n as u32).to_le_bytes());
    out.extend_from_slice(&(field_version as u32).to_le_bytes());
    for p in &set.positions {
        for x in p {
            out.extend_from_slice(&(*x as f32).to_le_bytes());
        }
    }
    for c in &set.colours {
        out.extend_from_slice(&[c[0], c[1], c[2], 255]);
    }
    for i in 0..n {
        let p = predicted.get(i).copied().unwrap_or(NO_CLASS);
        out.extend_from_slice(&p.to_le_bytes());
    }
    for t in &set.truth {
        out.extend_from_slice(&t.to_le_bytes());
    }
    for u in &set.uncertainty {
        out.extend_from_slice(&u.to_le_bytes());
    }
    out
}
