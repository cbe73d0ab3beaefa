//! What a loaded scene is, told from its content rather than from the file
//! format it came in: an object the cameras walk around (rendered or
//! photographed), a room they stand in, a forward-facing capture, or an open
//! scene whose content reaches far past the region the cameras look at.
//! `train` picks its defaults by this kind and prints it with its evidence.

use model::geometry::{Pose, SceneBox, Vec3, dot, norm, sub};

use crate::poses::focus_point;
use crate::scene::{Frame, Scene, SceneSource};

/// The kinds of capture whose defaults differ.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CaptureKind {
    /// Rendered views around an object on a plain background (a Blender
    /// scene): the object fills a known region, nothing lies beyond it.
    RenderedObject,
    /// Photographs taken walking around an object: the object is where the
    /// cameras look, its surroundings reach far past it.
    PhotographedObject,
    /// A room the cameras stand in, looking at its walls (a scan, a
    /// walk-through, the synthetic room).
    Room,
    /// Views that all face one way at a scene in front of them (LLFF).
    ForwardFacing,
    /// A scene whose measured depth reaches far past the region the cameras
    /// look at (a backdrop, the sky).
    OpenScene,
}

impl CaptureKind {
    /// Every kind, in the order the defaults table lists them.
    pub const ALL: [CaptureKind; 5] = [
        CaptureKind::RenderedObject,
        CaptureKind::PhotographedObject,
        CaptureKind::Room,
        CaptureKind::ForwardFacing,
        CaptureKind::OpenScene,
    ];

    /// The kind in words, as messages and the defaults table say it.
    pub fn describe(self) -> &'static str {
        match self {
            Self::RenderedObject => "a rendered object",
            Self::PhotographedObject => "a photographed object walked around",
            Self::Room => "a room stood in",
            Self::ForwardFacing => "a forward-facing capture",
            Self::OpenScene => "an open scene reaching far past its box",
        }
    }

    /// Whether the cameras look at the scene from outside it (an object or
    /// a forward-facing scene) rather than standing in it.
    pub fn seen_from_outside(self) -> bool {
        !matches!(self, Self::Room | Self::OpenScene)
    }
}

/// An angle under which a camera's axis counts as pointing at the common
/// focus point, degrees.
const AT_FOCUS_DEGREES: f64 = 15.0;
/// The length of the mean viewing direction above which all cameras face
/// one way.
const ONE_WAY: f64 = 0.9;
/// The share of depth points outside the scene box above which the content
/// reaches past it.
const PAST_THE_BOX: f64 = 0.25;
/// The share of a frame's pixels that must carry depth for it to count as
/// dense depth (sparse points cover far less).
const DENSE_DEPTH: f64 = 0.3;
/// The share of pixels equal to the image's corner colour from which a
/// frame has a plain (rendered) background.
const PLAIN_BACKGROUND: f64 = 0.1;
/// Frames looked at for the background and the depth, at most.
const FRAMES_SAMPLED: usize = 16;

/// What the kind was told from, measured on the loaded scene.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureEvidence {
    /// Cameras in the scene.
    pub cameras: usize,
    /// The point closest to every camera's optical axis (least squares,
    /// [`focus_point`]), `None` when the axes are (nearly) parallel.
    pub focus: Option<Vec3>,
    /// Cameras whose axis points within 15° of the focus
    /// point, in front of them.
    pub at_focus: usize,
    /// The length of the mean viewing direction (1: all face one way).
    pub direction_agreement: f64,
    /// Camera centres inside the scene box.
    pub inside_box: usize,
    /// Why the views are renders (`None`: photographs).
    pub rendered: Option<String>,
    /// The plain colour most rendered views have behind the object (`None`
    /// for photographs and the built-in scenes).
    pub plain_background: Option<[f32; 3]>,
    /// Frames (of those sampled) with dense depth.
    pub dense_depth_frames: usize,
    /// Frames with sparse depth targets (a few pixels, e.g. from points).
    pub sparse_depth_frames: usize,
    /// The share of sampled dense-depth points outside the scene box.
    pub depth_past_box: Option<f64>,
}

/// The kind of `scene` and the evidence it was told from.
pub fn capture_kind(scene: &Scene) -> (CaptureKind, CaptureEvidence) {
    let evidence = measure(scene);
    (kind_from(&evidence), evidence)
}

/// The decision, from the evidence alone.
pub fn kind_from(e: &CaptureEvidence) -> CaptureKind {
    let object = if e.rendered.is_some() {
        CaptureKind::RenderedObject
    } else {
        CaptureKind::PhotographedObject
    };
    if e.depth_past_box.is_some_and(|s| s > PAST_THE_BOX) {
        CaptureKind::OpenScene
    } else if e.depth_past_box.is_some() && most(e.inside_box, e.cameras) {
        // Measured depth all round the cameras: they stand in what they
        // see, however short the stretch of the walk.
        CaptureKind::Room
    } else if e.direction_agreement > ONE_WAY {
        CaptureKind::ForwardFacing
    } else if most(e.at_focus, e.cameras) {
        object
    } else {
        CaptureKind::Room
    }
}

/// Whether `some` of `all` is a majority (none of none is not).
pub fn most(some: usize, all: usize) -> bool {
    2 * some > all
}

/// How many of `centres` lie inside `scene_box`.
pub fn cameras_inside(scene_box: &SceneBox, centres: impl IntoIterator<Item = Vec3>) -> usize {
    centres
        .into_iter()
        .filter(|c| scene_box.contains(*c))
        .count()
}

impl CaptureEvidence {
    /// The evidence in words, for the line `train` prints.
    pub fn describe(&self) -> String {
        let mut parts = vec![format!(
            "{} of {} cameras point at one spot",
            self.at_focus, self.cameras
        )];
        parts.push(format!(
            "mean viewing direction {:.2} long",
            self.direction_agreement
        ));
        parts.push(format!("{} inside the scene box", self.inside_box));
        parts.push(match &self.rendered {
            Some(why) => format!("renders ({why})"),
            None => "photographs".into(),
        });
        if let Some(s) = self.depth_past_box {
            parts.push(format!("{:.0}% of the depth past the box", 100.0 * s));
        } else if self.sparse_depth_frames > 0 {
            parts.push(format!(
                "sparse depth in {} frames",
                self.sparse_depth_frames
            ));
        } else {
            parts.push("no depth".into());
        }
        parts.join(", ")
    }
}

fn measure(scene: &Scene) -> CaptureEvidence {
    let poses: Vec<Pose> = scene.frames.iter().map(|f| f.camera.pose).collect();
    let centres: Vec<Vec3> = poses.iter().map(Pose::center).collect();
    let axes: Vec<Vec3> = poses.iter().map(|p| unit(p.forward())).collect();
    let focus = focus_point(&poses);
    let at_focus = focus.map_or(0, |p| {
        let cos = AT_FOCUS_DEGREES.to_radians().cos();
        centres
            .iter()
            .zip(&axes)
            .filter(|(c, a)| {
                let to = sub(p, **c);
                let n = norm(to);
                n > 0.0 && dot(to, **a) / n > cos
            })
            .count()
    });
    let mean = axes
        .iter()
        .fold([0.0; 3], |m, a| [m[0] + a[0], m[1] + a[1], m[2] + a[2]]);
    let n = axes.len().max(1) as f64;
    let direction_agreement = norm(mean) / n;
    let inside_box = cameras_inside(&scene.scene_box, centres.iter().copied());
    let sampled = sample_frames(&scene.frames);
    let dense = |f: &Frame| f.depth.is_some() && depth_coverage(f) >= DENSE_DEPTH;
    let dense_frames = scene.frames.iter().filter(|f| dense(f)).count();
    let depth_frames = scene.frames.iter().filter(|f| f.depth.is_some()).count();
    let dense_sampled: Vec<&Frame> = sampled.iter().copied().filter(|f| dense(f)).collect();
    // Each sampled frame's plain background, measured once.
    let plain: Vec<(f64, [f32; 3])> = sampled.iter().filter_map(|f| plain_share(f)).collect();
    let mostly_plain = most(plain.len(), sampled.len());
    CaptureEvidence {
        cameras: centres.len(),
        focus,
        at_focus,
        direction_agreement,
        inside_box,
        rendered: rendered(scene, &plain, mostly_plain),
        plain_background: mostly_plain.then(|| plain[0].1),
        dense_depth_frames: dense_frames,
        sparse_depth_frames: depth_frames - dense_frames,
        depth_past_box: (!dense_sampled.is_empty()).then(|| past_box(scene, &dense_sampled)),
    }
}

fn unit(v: Vec3) -> Vec3 {
    let n = norm(v).max(f64::MIN_POSITIVE);
    [v[0] / n, v[1] / n, v[2] / n]
}

/// Up to [`FRAMES_SAMPLED`] frames spread over the capture.
fn sample_frames(frames: &[Frame]) -> Vec<&Frame> {
    let step = frames.len().div_ceil(FRAMES_SAMPLED).max(1);
    frames.iter().step_by(step).collect()
}

/// The share of a frame's depth pixels with a measurement.
fn depth_coverage(f: &Frame) -> f64 {
    f.depth.as_ref().map_or(0.0, |d| {
        let valid = (0..d.len()).filter(|&i| d.value(i) > 0.0).count();
        valid as f64 / d.len().max(1) as f64
    })
}

/// Why the views are renders, if they are: the built-in scene, or most
/// sampled frames on a plain background (`plain`: the share and colour of
/// each sampled frame that has one).
fn rendered(scene: &Scene, plain: &[(f64, [f32; 3])], mostly_plain: bool) -> Option<String> {
    if matches!(scene.source.base(), SceneSource::Synthetic { .. }) {
        return Some("the built-in synthetic scene".into());
    }
    if !mostly_plain {
        return None;
    }
    let mean = plain.iter().map(|(share, _)| share).sum::<f64>() / plain.len() as f64;
    Some(format!(
        "{:.0}% of the pixels are one plain background colour",
        100.0 * mean
    ))
}

/// The share of `f`'s pixels exactly its corners' colour (to 1/255), and
/// that colour, when all four corners agree on it and it is at least
/// [`PLAIN_BACKGROUND`].
fn plain_share(f: &Frame) -> Option<(f64, [f32; 3])> {
    let img = &f.rgb;
    let (w, h) = (img.width, img.height);
    if w == 0 || h == 0 {
        return None;
    }
    let corner = img.get(0, 0);
    let same = |c: [f32; 3]| (0..3).all(|k| (c[k] - corner[k]).abs() <= 1.0 / 255.0);
    if ![img.get(w - 1, 0), img.get(0, h - 1), img.get(w - 1, h - 1)]
        .into_iter()
        .all(same)
    {
        return None;
    }
    let total = (w as usize) * (h as usize);
    let equal = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| same(img.get(x, y)))
        .count();
    let share = equal as f64 / total as f64;
    (share >= PLAIN_BACKGROUND).then_some((share, corner))
}

/// The share of the frames' depth points (every 8th pixel in each axis)
/// that lie outside the scene box.
fn past_box(scene: &Scene, frames: &[&Frame]) -> f64 {
    let (mut outside, mut all) = (0usize, 0usize);
    for f in frames {
        let Some(d) = &f.depth else { continue };
        let cam = &f.camera;
        for y in (0..d.height).step_by(8) {
            for x in (0..d.width).step_by(8) {
                let z = f64::from(d.get(x, y));
                if z <= 0.0 || !z.is_finite() {
                    continue;
                }
                // Depth pixel centres in the colour camera's image points.
                let u = (f64::from(x) + 0.5) * f64::from(cam.intrinsics.width) / f64::from(d.width)
                    - 0.5;
                let v = (f64::from(y) + 0.5) * f64::from(cam.intrinsics.height)
                    / f64::from(d.height)
                    - 0.5;
                let dir = cam.intrinsics.camera_direction(u, v);
                let p = cam.pose.camera_to_world([dir[0] * z, dir[1] * z, z]);
                all += 1;
                outside += usize::from(!scene.scene_box.contains(p));
            }
        }
    }
    if all == 0 {
        0.0
    } else {
        outside as f64 / all as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn evidence(at_focus: usize, agreement: f64) -> CaptureEvidence {
        CaptureEvidence {
            cameras: 10,
            focus: Some([0.0; 3]),
            at_focus,
            direction_agreement: agreement,
            inside_box: 0,
            rendered: None,
            plain_background: None,
            dense_depth_frames: 0,
            sparse_depth_frames: 0,
            depth_past_box: None,
        }
    }

    #[test]
    fn the_kind_follows_the_evidence() {
        assert_eq!(
            kind_from(&evidence(9, 0.3)),
            CaptureKind::PhotographedObject
        );
        let rendered = CaptureEvidence {
            rendered: Some("plain".into()),
            ..evidence(9, 0.3)
        };
        assert_eq!(kind_from(&rendered), CaptureKind::RenderedObject);
        assert_eq!(kind_from(&evidence(5, 0.3)), CaptureKind::Room);
        assert_eq!(
            kind_from(&evidence(6, 0.3)),
            CaptureKind::PhotographedObject
        );
        assert_eq!(kind_from(&evidence(10, 0.95)), CaptureKind::ForwardFacing);
        // A few steps of a room scan all face one way; its depth says room.
        let scan = CaptureEvidence {
            depth_past_box: Some(0.0),
            inside_box: 10,
            ..evidence(0, 0.99)
        };
        assert_eq!(kind_from(&scan), CaptureKind::Room);
        let open = CaptureEvidence {
            depth_past_box: Some(0.5),
            ..evidence(10, 0.95)
        };
        assert_eq!(kind_from(&open), CaptureKind::OpenScene);
        let room = CaptureEvidence {
            depth_past_box: Some(0.01),
            ..evidence(0, 0.1)
        };
        assert_eq!(kind_from(&room), CaptureKind::Room);
    }

    #[test]
    fn most_cameras_inside_the_box_is_a_majority_of_them() {
        let b = SceneBox {
            min: [-1.0; 3],
            max: [1.0; 3],
        };
        // A walk through the box, and an orbit around it at radius 4.
        let walk = (0..10).map(|i| [-0.9 + 0.2 * i as f64, 0.0, 0.3]);
        let orbit = (0..10).map(|i| {
            let a = i as f64 * 0.6;
            [4.0 * a.cos(), 4.0 * a.sin(), 0.5]
        });
        assert_eq!(cameras_inside(&b, walk.clone()), 10);
        assert!(most(10, 10));
        assert_eq!(cameras_inside(&b, orbit.clone()), 0);
        assert!(!most(0, 10));
        // Half inside is not a majority; one more inside is.
        let half: Vec<Vec3> = walk.clone().take(5).chain(orbit.clone().take(5)).collect();
        assert_eq!(cameras_inside(&b, half.clone()), 5);
        assert!(!most(5, 10));
        let more: Vec<Vec3> = half.into_iter().chain(walk.take(1)).collect();
        assert_eq!(cameras_inside(&b, more.clone()), 6);
        assert!(most(6, more.len()));
        assert_eq!(cameras_inside(&b, std::iter::empty()), 0);
        assert!(!most(0, 0));
    }
}
