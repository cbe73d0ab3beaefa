//! Novel cameras aimed at uncertain points (the guided mode): targets drawn with probability
//! equal to their normalised uncertainty and spread apart, a position on the
//! free side of each target, and checks against the field that the camera is
//! in empty space, sees its target, and renders it with the colour the
//! capture saw there.

use burn::tensor::{Device, Tensor, TensorData};
use model::geometry::{Camera, Intrinsics, SceneBox, Vec3, add_scaled, look_at, norm, sub};
use model::{FeatureMode, OpenNerf, RenderRequest};
use rand::Rng;

use crate::render::{RENDER_MIN_NEAR, tensor_to_vec};
use crate::uncertainty::UncertaintyMap;

/// Targets drawn per view wanted: a partly trained field rejects many
/// positions (fog in free space hides the target), so spare targets are
/// drawn and the first `max_views` that pass are kept.
pub const SPARE_TARGETS: usize = 4;

/// Pixels a side of the patch at the image centre whose rendered colour is
/// compared with the target's observed colour.
const COLOR_PATCH: i32 = 3;

/// RMS over the channels of `rendered - seen`.
pub fn color_error(rendered: [f64; 3], seen: [f32; 3]) -> f64 {
    let s: f64 = (0..3).map(|k| (rendered[k] - seen[k] as f64).powi(2)).sum();
    (s / 3.0).sqrt()
}

/// Settings of the camera proposals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProposalOptions {
    /// Most cameras proposed.
    pub max_views: usize,
    /// Distance of the camera from its target along the free-side normal, metres.
    pub offset: f64,
    /// Standard deviation of the noise added to the position, metres.
    pub noise: f64,
    /// Targets closer than this to an accepted one are skipped, metres.
    pub min_separation: f64,
    /// Positions tried per target before it is given up.
    pub retries: usize,
    /// A position is rejected where the field's density (per metre) exceeds this.
    pub max_density: f64,
    /// A position is rejected where the transmittance to the target is below this.
    pub min_transmittance: f64,
    /// A position is rejected where the field renders the target with a
    /// colour further than this (RMS over the channels, colours in [0, 1])
    /// from the mean colour the training frames saw it with: where the field
    /// has not learnt a surface its render is wrong, and the 2D extractor
    /// would label the wrong render, teaching the field its own error.
    /// Infinity (the default) measures the difference without rejecting.
    pub max_color_error: f64,
}

impl Default for ProposalOptions {
    fn default() -> Self {
        Self {
            max_views: 8,
            offset: 0.5,
            noise: 0.05,
            min_separation: 0.5,
            retries: 20,
            max_density: 1.0,
            min_transmittance: 0.5,
            max_color_error: f64::INFINITY,
        }
    }
}

/// The chance of each point to become a target: its normalised
/// uncertainty where a training view saw it, 0 where none did.
///
/// Points no view saw carry the largest uncertainty, but the field was never
/// shown them either: a camera aimed there renders unsupervised fog (on the
/// synthetic rooms, the ceiling no capture looks at), and the features the
/// extractor reads off that render would teach the field noise. The views
/// go where the field can render what it saw and the features disagree.
pub fn target_chances(map: &UncertaintyMap) -> Vec<f64> {
    map.normalised
        .iter()
        .zip(&map.counts)
        .map(|(&u, &n)| if n == 0 { 0.0 } else { u })
        .collect()
}

/// Targets drawn as in the paper (Sec. 3.3): point `i` is a candidate when `x < u_i` for
/// `x ~ U[0, 1]`; candidates are visited in random order and kept when no
/// kept target is within `min_separation`. Returns at most `max` indices.
pub fn select_targets(
    normalised: &[f64],
    positions: &[Vec3],
    max: usize,
    min_separation: f64,
    rng: &mut impl Rng,
) -> Vec<usize> {
    let mut candidates: Vec<usize> = (0..normalised.len())
        .filter(|&i| rng.random::<f64>() < normalised[i])
        .collect();
    // Fisher-Yates: a seeded, uniform visiting order.
    for i in (1..candidates.len()).rev() {
        let j = rng.random_range(0..=i);
        candidates.swap(i, j);
    }
    let mut kept: Vec<usize> = Vec::new();
    for c in candidates {
        if kept.len() >= max {
            break;
        }
        if kept
            .iter()
            .all(|&k| norm(sub(positions[k], positions[c])) >= min_separation)
        {
            kept.push(c);
        }
    }
    kept
}

/// The unit direction from `target` towards the free side: towards the mean
/// centre of the cameras that saw it, else towards `fallback` (e.g. the
/// mean of all cameras). `None` when both coincide with the target.
pub fn free_side(target: Vec3, seen_from: Option<Vec3>, fallback: Vec3) -> Option<Vec3> {
    [seen_from, Some(fallback)]
        .into_iter()
        .flatten()
        .find_map(|c| {
            let d = sub(c, target);
            let n = norm(d);
            (n > 1e-9).then(|| d.map(|v| v / n))
        })
}

/// Density (per metre) and transmittance towards a target, from the field.
pub struct FieldProbe<'a> {
    /// The trained field.
    pub model: &'a OpenNerf,
    /// The scene box the field's coordinates are normalised in.
    pub scene_box: &'a SceneBox,
    /// Inference device.
    pub device: &'a Device,
    /// Samples along the segment for the transmittance.
    pub samples: usize,
    /// Colour of empty space the field was trained with.
    pub background: Option<[f32; 3]>,
}

impl FieldProbe<'_> {
    /// Field density per metre at world points. The field's density is per
    /// unit of normalised length, and one metre is `scale` normalised units.
    pub fn density(&self, points: &[Vec3]) -> Vec<f64> {
        let scale = self.scene_box.scale();
        let flat: Vec<f32> = points
            .iter()
            .flat_map(|&p| self.scene_box.normalize_point(p).map(|x| x as f32))
            .collect();
        let t = Tensor::<2>::from_data(TensorData::new(flat, [points.len(), 3]), self.device);
        let d = self.model.query_density(t, 1e-3 * scale as f32);
        tensor_to_vec(d)
            .into_iter()
            .map(|x| x as f64 * scale)
            .collect()
    }

    /// Transmittance from `from` to just before `to` (the last 10% of the
    /// segment, where the target's own surface is, is left out): the
    /// midpoint rule on `samples` points.
    pub fn transmittance(&self, from: Vec3, to: Vec3) -> f64 {
        let n = self.samples.max(2);
        let d = sub(to, from);
        let len = 0.9 * norm(d);
        let pts: Vec<Vec3> = (0..n)
            .map(|i| add_scaled(from, 0.9 * (i as f64 + 0.5) / n as f64, d))
            .collect();
        let optical: f64 = self
            .density(&pts)
            .iter()
            .map(|s| s.max(0.0) * len / n as f64)
            .sum();
        (-optical).exp()
    }
}

impl FieldProbe<'_> {
    /// Mean rendered colour of the `COLOR_PATCH`-pixel square at the image
    /// centre of `camera` (where a camera made by `look_at` sees its target).
    pub fn centre_color(&self, camera: &Camera) -> [f64; 3] {
        let k = &camera.intrinsics;
        let r = COLOR_PATCH / 2;
        let rays: Vec<_> = (-r..=r)
            .flat_map(|j| (-r..=r).map(move |i| (i, j)))
            .map(|(i, j)| {
                let ray = camera.ray(k.cx + i as f64, k.cy + j as f64);
                self.scene_box.normalize_ray(&ray, RENDER_MIN_NEAR)
            })
            .collect();
        let request = RenderRequest::inference(&rays)
            .with_chunk(rays.len())
            .with_features(FeatureMode::None)
            .with_background(self.background);
        let out = self
            .model
            .render(&request)
            .expect("never cancelled without an observer");
        let n = (out.rgb.len() / 3).max(1) as f64;
        let mut mean = [0.0; 3];
        for px in out.rgb.chunks(3) {
            (0..3).for_each(|c| mean[c] += px[c] as f64 / n);
        }
        mean
    }

    /// The paper's checks (Sec. 3.3) of `camera` for target `t`: its centre inside the
    /// scene box, density there at most `max_density` per metre,
    /// transmittance to `t` at least `min_transmittance`; and, where the
    /// target's observed colour `seen` is known, the field's render of the
    /// target within `max_color_error` of it (the difference is returned).
    pub fn accept(
        &self,
        camera: &Camera,
        t: Vec3,
        seen: Option<[f32; 3]>,
        opts: &ProposalOptions,
    ) -> Option<Accepted> {
        let p = camera.pose.center();
        if !self.scene_box.contains(p) || self.density(&[p])[0] > opts.max_density {
            return None;
        }
        let transmittance = self.transmittance(p, t);
        if transmittance < opts.min_transmittance {
            return None;
        }
        let color_error = match seen {
            Some(seen) => {
                let e = color_error(self.centre_color(camera), seen);
                if e.is_nan() || e > opts.max_color_error {
                    return None;
                }
                Some(e)
            }
            None => None,
        };
        Some(Accepted {
            transmittance,
            color_error,
        })
    }
}

/// What the checks of a usable camera measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Accepted {
    /// Transmittance from the camera to the target.
    pub transmittance: f64,
    /// RMS colour difference of the render at the target from the colour the
    /// capture saw there (`None`: not checked).
    pub color_error: Option<f64>,
}

/// A proposed view and how it was found.
#[derive(Debug, Clone, PartialEq)]
pub struct Proposal {
    /// Index of the target point.
    pub target: usize,
    /// The camera, looking at the target.
    pub camera: Camera,
    /// Attempts used (1 = the first position was accepted).
    pub attempts: usize,
    /// Transmittance from the camera to the target.
    pub transmittance: f64,
    /// Colour difference of the render at the target (see [`Accepted`]).
    pub color_error: Option<f64>,
}

/// One camera per target where a position passes `accept` within
/// `opts.retries` attempts: `p = t + offset n + noise` with `n` towards the
/// free side, looking at `t` with `up`; `accept(camera, target index)`
/// measures a usable camera and rejects the others (see
/// [`FieldProbe::accept`]).
#[allow(clippy::too_many_arguments)]
pub fn propose_cameras(
    map: &UncertaintyMap,
    positions: &[Vec3],
    targets: &[usize],
    intrinsics: Intrinsics,
    up: Vec3,
    fallback_centre: Vec3,
    mut accept: impl FnMut(&Camera, usize) -> Option<Accepted>,
    opts: &ProposalOptions,
    rng: &mut impl Rng,
) -> Vec<Proposal> {
    let mut out = Vec::new();
    for &t in targets {
        if out.len() >= opts.max_views {
            break;
        }
        let target = positions[t];
        let Some(n) = free_side(target, map.mean_view_centres[t], fallback_centre) else {
            continue;
        };
        for attempt in 1..=opts.retries.max(1) {
            let jitter: Vec3 = std::array::from_fn(|_| gaussian(rng) * opts.noise);
            let p = add_scaled(add_scaled(target, opts.offset, n), 1.0, jitter);
            let Ok(pose) = look_at(p, target, up) else {
                continue;
            };
            let camera = Camera { intrinsics, pose };
            let Some(checks) = accept(&camera, t) else {
                continue;
            };
            out.push(Proposal {
                target: t,
                camera,
                attempts: attempt,
                transmittance: checks.transmittance,
                color_error: checks.color_error,
            });
            break;
        }
    }
    out
}

/// Guided cameras and the number of targets they were drawn from.
#[derive(Debug, Clone, PartialEq)]
pub struct GuidedProposals {
    /// Targets drawn (spares included, see [`SPARE_TARGETS`]).
    pub targets_drawn: usize,
    /// The accepted cameras, at most `opts.max_views`.
    pub proposals: Vec<Proposal>,
}

/// Draws targets by uncertainty ([`select_targets`] over
/// [`target_chances`], [`SPARE_TARGETS`] per view wanted) and proposes a
/// camera for each until `opts.max_views` pass the field's checks.
/// `centre` is where the capture stood (the fallback free side).
#[allow(clippy::too_many_arguments)]
pub fn guided_proposals(
    map: &UncertaintyMap,
    points: &[Vec3],
    intrinsics: Intrinsics,
    up: Vec3,
    centre: Vec3,
    probe: &FieldProbe<'_>,
    opts: &ProposalOptions,
    rng: &mut impl Rng,
) -> GuidedProposals {
    let targets = select_targets(
        &target_chances(map),
        points,
        opts.max_views.saturating_mul(SPARE_TARGETS),
        opts.min_separation,
        rng,
    );
    let proposals = propose_cameras(
        map,
        points,
        &targets,
        intrinsics,
        up,
        centre,
        |camera, t| probe.accept(camera, points[t], map.mean_colors[t], opts),
        opts,
        rng,
    );
    GuidedProposals {
        targets_drawn: targets.len(),
        proposals,
    }
}

/// A standard normal draw (Box-Muller).
pub(crate) fn gaussian(rng: &mut impl Rng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn targets_follow_the_uncertainty_and_stay_apart() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        // Points on a line 0.1 m apart; only the second half is uncertain.
        let pos: Vec<Vec3> = (0..100).map(|i| [i as f64 * 0.1, 0.0, 0.0]).collect();
        let u: Vec<f64> = (0..100).map(|i| if i < 50 { 0.0 } else { 1.0 }).collect();
        // A greedy choice 0.15 m apart on this 0.1 m grid leaves gaps of at
        // most 0.3 m over the 4.9 m of uncertain points, so at least 17 fit:
        // the cap of 10 is reached whatever the draw.
        let t = select_targets(&u, &pos, 10, 0.15, &mut rng);
        assert_eq!(t.len(), 10);
        assert!(t.iter().all(|&i| i >= 50), "{t:?}");
        for (a, &i) in t.iter().enumerate() {
            for &j in &t[a + 1..] {
                assert!(norm(sub(pos[i], pos[j])) >= 0.15);
            }
        }
        // 0.45 m apart on 4.9 m: at most 11 fit, and gaps of at most 0.9 m
        // leave at least 7.
        let wide = select_targets(&u, &pos, 100, 0.45, &mut rng);
        assert!((7..=11).contains(&wide.len()), "{}", wide.len());
        // A certain cloud yields nothing; the cap holds.
        assert!(select_targets(&[0.0; 100], &pos, 10, 0.0, &mut rng).is_empty());
        assert_eq!(select_targets(&[1.0; 100], &pos, 3, 0.0, &mut rng).len(), 3);
    }

    #[test]
    fn points_no_view_saw_are_never_targets() {
        let map = UncertaintyMap {
            counts: vec![0, 1, 5, 0],
            log_det: vec![2.0, 2.0, 1.0, 2.0],
            normalised: vec![1.0, 1.0, 0.25, 1.0],
            mean_features: vec![None; 4],
            mean_view_centres: vec![None; 4],
            mean_colors: vec![None; 4],
            k: 1,
            failed_factorisations: 0,
        };
        assert_eq!(target_chances(&map), vec![0.0, 1.0, 0.25, 0.0]);
        let pos: Vec<Vec3> = (0..4).map(|i| [i as f64, 0.0, 0.0]).collect();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for _ in 0..50 {
            let t = select_targets(&target_chances(&map), &pos, 4, 0.0, &mut rng);
            assert!(
                t.contains(&1) && !t.contains(&0) && !t.contains(&3),
                "{t:?}"
            );
        }
    }

    #[test]
    fn cameras_sit_on_the_free_side_look_at_their_target_and_avoid_rejected_spots() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let positions = vec![[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
        let map = UncertaintyMap {
            counts: vec![3, 3],
            log_det: vec![0.0, 0.0],
            normalised: vec![1.0, 1.0],
            mean_features: vec![None, None],
            mean_view_centres: vec![Some([0.0, 0.0, 4.0]), Some([3.0, 4.0, 0.0])],
            mean_colors: vec![None, None],
            k: 1,
            failed_factorisations: 0,
        };
        let k = Intrinsics::from_fov_x(64, 48, 1.0);
        let opts = ProposalOptions::default();
        // The second target's free side is blocked everywhere.
        let accept = |c: &Camera, _t: usize| {
            (c.pose.center()[0] < 1.5).then_some(Accepted {
                transmittance: 0.9,
                color_error: None,
            })
        };
        let got = propose_cameras(
            &map,
            &positions,
            &[0, 1],
            k,
            [0.0, 1.0, 0.0],
            [0.0; 3],
            accept,
            &opts,
            &mut rng,
        );
        assert_eq!(got.len(), 1);
        let p = &got[0];
        assert_eq!(p.target, 0);
        let c = p.camera.pose.center();
        // Above the target (towards its observers), offset 0.5 m give or take the noise.
        assert!((c[2] - 0.5).abs() < 0.25 && c[0].abs() < 0.25, "{c:?}");
        // The target projects to the image centre.
        let proj = p.camera.project(positions[0]).expect("in front");
        assert!((proj.u - k.cx).abs() < 1e-6 && (proj.v - k.cy).abs() < 1e-6);
        assert!(p.attempts >= 1 && p.attempts <= opts.retries);
    }

    #[test]
    fn the_free_side_points_to_the_observers() {
        let n = free_side([0.0; 3], Some([0.0, 0.0, 2.0]), [5.0, 0.0, 0.0]).expect("n");
        assert!((n[2] - 1.0).abs() < 1e-12);
        let n = free_side([0.0; 3], None, [0.0, -3.0, 0.0]).expect("n");
        assert!((n[1] + 1.0).abs() < 1e-12);
        assert!(free_side([1.0; 3], Some([1.0; 3]), [1.0; 3]).is_none());
    }
}
