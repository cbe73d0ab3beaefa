//! Render requests, one at a time: a request cancels the ones before it
//! (the page only wants the latest view), a worker thread renders chunk by
//! chunk so that progress shows and a cancel stops it within a chunk.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use image::ImageEncoder;
use model::geometry::{Camera, Distortion, Intrinsics, Pose};

use crate::ViewerError;
use crate::query::{QueryRequest, resolve, score_points, scores};
use crate::state::Viewer;
use field_ops::depth_image::{DepthQuantity, DepthScale};
use field_ops::images::ViewImages;
use field_ops::query::{RelevancyScale, relevancy_overlay};
use field_ops::render::{ViewSettings, render_view};

/// Finished jobs kept for their images.
const KEPT: usize = 16;

/// A camera as the page sends it (OpenCV: rotation columns are the camera's
/// right, down and forward axes in world coordinates, row-major).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraRequest {
    /// Camera-to-world rotation, row-major.
    pub rotation: [f64; 9],
    /// Camera centre.
    pub position: [f64; 3],
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x.
    pub cx: f64,
    /// Principal point y.
    pub cy: f64,
}

impl CameraRequest {
    /// The camera, checked: finite numbers, a size within `1..=max_side`,
    /// positive focal lengths and a rotation (orthonormal, determinant 1).
    pub fn camera(&self, max_side: u32) -> Result<Camera, ViewerError> {
        let bad = |m: String| Err(ViewerError::BadRequest(format!("camera: {m}")));
        let numbers = self.rotation.iter().chain(&self.position);
        if numbers
            .chain([&self.fx, &self.fy, &self.cx, &self.cy])
            .any(|x| !x.is_finite())
        {
            return bad("every number must be finite".into());
        }
        for (name, side) in [("width", self.width), ("height", self.height)] {
            if side == 0 || side > max_side {
                return bad(format!("{name} {side} is outside 1..={max_side}"));
            }
        }
        if self.fx <= 0.0 || self.fy <= 0.0 {
            return bad("focal lengths must be positive".into());
        }
        let r: [[f64; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|j| self.rotation[3 * i + j]));
        let m = nalgebra::Matrix3::from_fn(|i, j| r[i][j]);
        if (m.transpose() * m - nalgebra::Matrix3::identity())
            .abs()
            .max()
            > 1e-3
            || (m.determinant() - 1.0).abs() > 1e-3
        {
            return bad("rotation is not a rotation matrix (orthonormal, determinant 1)".into());
        }
        Ok(Camera {
            intrinsics: Intrinsics {
                width: self.width,
                height: self.height,
                fx: self.fx,
                fy: self.fy,
                cx: self.cx,
                cy: self.cy,
                distortion: Distortion::NONE,
            },
            pose: Pose {
                rotation: r,
                translation: self.position,
            },
        })
    }
}

/// A render request.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderRequest {
    /// Where to render from.
    pub camera: CameraRequest,
    /// Adds a relevancy image of this query.
    #[serde(default)]
    pub query: Option<QueryRequest>,
}

/// Where a job is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum JobState {
    /// Waiting for the worker.
    Queued,
    /// Rendering.
    Running,
    /// Images ready.
    Done,
    /// Stopped by a cancel or a newer request.
    Cancelled,
    /// Failed; the error says why.
    Failed,
}

/// One render request and what became of it.
#[derive(Debug)]
pub struct Job {
    /// Its number.
    pub id: u64,
    request: RenderRequest,
    camera: Camera,
    state: Mutex<(JobState, Option<String>)>,
    cancel: AtomicBool,
    progress: AtomicU32,
    images: Mutex<Vec<(String, Vec<u8>)>>,
    depth_scale: Mutex<Option<DepthScale>>,
}

/// A job's state as the API reports it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct JobStatus {
    /// Its number.
    pub job: u64,
    /// Where it is.
    pub state: JobState,
    /// Fraction of rays rendered.
    pub progress: f32,
    /// Why it failed.
    pub error: Option<String>,
    /// Names of the finished images (`rgb`, `depth`, `opacity`, `relevancy`).
    pub images: Vec<String>,
    /// What the depth image's colours stand for, once it is finished.
    pub depth_scale: Option<DepthScale>,
    /// The depth scale in one line, for a caption.
    pub depth_caption: Option<String>,
}

impl Job {
    /// Its state, progress and images' names.
    pub fn status(&self) -> JobStatus {
        let (state, error) = self.state.lock().unwrap_or_else(|e| e.into_inner()).clone();
        let depth_scale = self
            .depth_scale
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        JobStatus {
            job: self.id,
            state,
            progress: f32::from_bits(self.progress.load(Ordering::Relaxed)),
            error,
            images: self.image_names(),
            depth_caption: depth_scale.as_ref().map(|d| d.caption()),
            depth_scale,
        }
    }

    /// Names of the finished images.
    pub fn image_names(&self) -> Vec<String> {
        let images = self.images.lock().unwrap_or_else(|e| e.into_inner());
        images.iter().map(|(n, _)| n.clone()).collect()
    }

    /// The finished image `name` as PNG bytes.
    pub fn image(&self, name: &str) -> Option<Vec<u8>> {
        let images = self.images.lock().unwrap_or_else(|e| e.into_inner());
        images
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, b)| b.clone())
    }

    /// Asks the job to stop; a queued one never starts.
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        if s.0 == JobState::Queued {
            s.0 = JobState::Cancelled;
        }
    }

    fn set(&self, state: JobState, error: Option<String>) {
        *self.state.lock().unwrap_or_else(|e| e.into_inner()) = (state, error);
    }

    fn finished(&self) -> bool {
        let s = self.state.lock().unwrap_or_else(|e| e.into_inner()).0;
        matches!(s, JobState::Done | JobState::Cancelled | JobState::Failed)
    }
}

#[derive(Debug, Default)]
struct Table {
    next: u64,
    recent: VecDeque<Arc<Job>>,
    queue: VecDeque<Arc<Job>>,
}

/// The job table and the worker's wake-up.
#[derive(Debug, Default)]
pub struct Jobs {
    table: Mutex<Table>,
    wake: Condvar,
    stop: AtomicBool,
}

impl Jobs {
    fn table(&self) -> std::sync::MutexGuard<'_, Table> {
        self.table.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Queues a render of `camera`, cancelling every earlier job.
    pub fn submit(&self, request: RenderRequest, camera: Camera) -> Arc<Job> {
        let mut t = self.table();
        for j in &t.recent {
            j.cancel();
        }
        t.queue.clear();
        t.next += 1;
        let job = Arc::new(Job {
            id: t.next,
            request,
            camera,
            state: Mutex::new((JobState::Queued, None)),
            cancel: AtomicBool::new(false),
            progress: AtomicU32::new(0),
            images: Mutex::new(Vec::new()),
            depth_scale: Mutex::new(None),
        });
        t.recent.push_back(job.clone());
        while t.recent.len() > KEPT && t.recent.front().is_some_and(|j| j.finished()) {
            t.recent.pop_front();
        }
        t.queue.push_back(job.clone());
        self.wake.notify_all();
        job
    }

    /// The job numbered `id`, while it is kept.
    pub fn get(&self, id: u64) -> Option<Arc<Job>> {
        self.table().recent.iter().find(|j| j.id == id).cloned()
    }

    /// Stops the worker after its current chunk.
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
        for j in &self.table().recent {
            j.cancel();
        }
        self.wake.notify_all();
    }

    /// The worker: renders queued jobs until [`Jobs::stop`].
    pub fn work(&self, viewer: &Viewer) {
        while !self.stop.load(Ordering::Relaxed) {
            let next = {
                let mut t = self.table();
                match t.queue.pop_front() {
                    Some(j) => Some(j),
                    None => {
                        let (mut t, _) = self
                            .wake
                            .wait_timeout(t, Duration::from_millis(200))
                            .unwrap_or_else(|e| e.into_inner());
                        t.queue.pop_front()
                    }
                }
            };
            if let Some(job) = next
                && !job.cancel.load(Ordering::Relaxed)
            {
                job.set(JobState::Running, None);
                match render(viewer, &job) {
                    Ok(true) => job.set(JobState::Done, None),
                    Ok(false) => job.set(JobState::Cancelled, None),
                    Err(e) => job.set(JobState::Failed, Some(e.to_string())),
                }
            }
        }
    }
}

/// Renders `job`; `false` when it was cancelled.
fn render(viewer: &Viewer, job: &Job) -> Result<bool, ViewerError> {
    let d = &viewer.data;
    let query = match &job.request.query {
        Some(q) if !q.positives.trim().is_empty() => {
            // Embedded once, for the points' scale and the pixels alike.
            let q = resolve(viewer, q)?;
            let on_points = score_points(viewer, &q)?;
            Some((q, on_points))
        }
        _ => None,
    };
    let field = viewer.field();
    let go = |done: usize, total: usize| {
        let p = if total == 0 {
            1.0
        } else {
            done as f32 / total as f32
        };
        job.progress.store(p.to_bits(), Ordering::Relaxed);
        !job.cancel.load(Ordering::Relaxed)
    };
    let settings = ViewSettings::new(d.meta.background, d.options.chunk)
        .with_features(query.is_some())
        .with_observer(&go);
    let Ok(v) = render_view(&field.model, &job.camera, &d.meta.scene_box, &settings) else {
        return Ok(false);
    };
    let (w, h) = (v.width, v.height);
    let pictures = ViewImages::of(&v, DepthQuantity::of(&field.model));
    let mut images = vec![
        ("rgb".to_string(), png(w, h, &pictures.rgb)?),
        ("depth".to_string(), png(w, h, &pictures.depth)?),
        ("opacity".to_string(), png(w, h, &pictures.opacity)?),
    ];
    if let Some((q, on_points)) = query {
        let s = scores(&v.feature, &q, d.meta.pca.as_ref())?;
        // The points' scale: the image and the cloud share one colour bar.
        let scale = RelevancyScale {
            lo: on_points.lo,
            hi: on_points.hi,
        };
        let overlay = relevancy_overlay(&v.rgb, &scale.apply(&s));
        images.push(("relevancy".to_string(), png(w, h, &overlay)?));
    }
    *job.images.lock().unwrap_or_else(|e| e.into_inner()) = images;
    *job.depth_scale.lock().unwrap_or_else(|e| e.into_inner()) = Some(pictures.depth_scale);
    Ok(!job.cancel.load(Ordering::Relaxed))
}

/// PNG bytes of an RGB8 image.
pub fn png(w: u32, h: u32, rgb: &[u8]) -> Result<Vec<u8>, ViewerError> {
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(rgb, w, h, image::ExtendedColorType::Rgb8)
        .map_err(|e| ViewerError::BadRequest(format!("cannot encode the image: {e}")))?;
    Ok(out)
}
