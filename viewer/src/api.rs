//! The JSON API: one function per endpoint, each returning a [`Reply`]
//! that [`crate::http`] sends. The routes are listed in the README.

use std::io::Write;

use serde_json::{Value, json};

use crate::ViewerError;
use crate::jobs::{Jobs, RenderRequest};
use crate::points::encode;
use crate::query::{CANONICAL_NEGATIVES, QueryRequest, query_points};
use crate::state::Viewer;
use field_ops::colormap::class_color;

/// The page, embedded so that it works offline.
pub const INDEX_HTML: &str = include_str!("../assets/index.html");
/// The page's script.
pub const VIEWER_JS: &str = include_str!("../assets/viewer.js");
/// The page's style sheet.
pub const VIEWER_CSS: &str = include_str!("../assets/viewer.css");

/// Request bodies are refused above this size (a query or a camera is a
/// few hundred bytes).
pub const MAX_BODY: usize = 64 * 1024;

/// An answer to a request.
#[derive(Debug, Clone, PartialEq)]
pub struct Reply {
    /// HTTP status.
    pub status: u16,
    /// `Content-Type`.
    pub content_type: &'static str,
    /// The body.
    pub body: Vec<u8>,
    /// A download's file name (`Content-Disposition: attachment`).
    pub filename: Option<String>,
}

impl Reply {
    /// A JSON reply.
    pub fn json(status: u16, value: &Value) -> Self {
        Self {
            status,
            content_type: "application/json",
            body: value.to_string().into_bytes(),
            filename: None,
        }
    }

    /// An error as `{"error": "..."}` with its status.
    pub fn error(e: &ViewerError) -> Self {
        Self::json(e.status(), &json!({ "error": e.to_string() }))
    }

    fn bytes(content_type: &'static str, body: Vec<u8>) -> Self {
        Self {
            status: 200,
            content_type,
            body,
            filename: None,
        }
    }
}

/// Answers `method path` with `body`.
pub fn handle(viewer: &Viewer, jobs: &Jobs, method: &str, path: &str, body: &[u8]) -> Reply {
    route(viewer, jobs, method, path, body).unwrap_or_else(|e| Reply::error(&e))
}

fn route(
    viewer: &Viewer,
    jobs: &Jobs,
    method: &str,
    path: &str,
    body: &[u8],
) -> Result<Reply, ViewerError> {
    let path = path.split(['?', '#']).next().unwrap_or("");
    if path
        .split('/')
        .any(|p| p == ".." || p.contains("%2e%2e") || p.contains("%2E%2E"))
    {
        return Err(ViewerError::BadRequest(format!(
            "{path}: paths that leave the page are refused (the viewer serves no files of the \
             run directory)"
        )));
    }
    let segments: Vec<&str> = path.trim_matches('/').split('/').collect();
    match (method, segments.as_slice()) {
        ("GET", [""]) | ("GET", ["index.html"]) => Ok(Reply::bytes(
            "text/html; charset=utf-8",
            INDEX_HTML.as_bytes().to_vec(),
        )),
        ("GET", ["viewer.js"]) => Ok(Reply::bytes(
            "text/javascript; charset=utf-8",
            VIEWER_JS.as_bytes().to_vec(),
        )),
        ("GET", ["viewer.css"]) => Ok(Reply::bytes(
            "text/css; charset=utf-8",
            VIEWER_CSS.as_bytes().to_vec(),
        )),
        ("GET", ["api", "summary"]) => Ok(Reply::json(200, &summary(viewer))),
        ("GET", ["api", "classes"]) => Ok(Reply::json(200, &classes(viewer))),
        ("GET", ["api", "points"]) => {
            let f = viewer.point_features();
            Ok(Reply::bytes(
                "application/octet-stream",
                encode(&viewer.data.points, &f.predicted, f.version),
            ))
        }
        ("GET", ["api", "cameras"]) => Ok(Reply::json(200, &cameras(viewer))),
        ("GET", ["api", "curve"]) => Ok(Reply::json(200, &curve(viewer))),
        ("POST", ["api", "query"]) => {
            let req: QueryRequest = parse(body)?;
            let r = query_points(viewer, &req)?;
            Ok(Reply::json(
                200,
                &serde_json::to_value(r).unwrap_or(Value::Null),
            ))
        }
        ("POST", ["api", "export"]) => export(viewer, body),
        ("POST", ["api", "render"]) => {
            let req: RenderRequest = parse(body)?;
            let camera = req.camera.camera(viewer.data.options.max_render_side)?;
            let job = jobs.submit(req, camera);
            Ok(Reply::json(202, &json!({ "job": job.id })))
        }
        ("GET", ["api", "render", id]) => {
            let job = job(jobs, id)?;
            Ok(Reply::json(
                200,
                &serde_json::to_value(job.status()).unwrap_or(Value::Null),
            ))
        }
        ("DELETE", ["api", "render", id]) | ("POST", ["api", "render", id, "cancel"]) => {
            let job = job(jobs, id)?;
            job.cancel();
            Ok(Reply::json(
                200,
                &serde_json::to_value(job.status()).unwrap_or(Value::Null),
            ))
        }
        ("GET", ["api", "render", id, file]) => {
            let job = job(jobs, id)?;
            let name = file.strip_suffix(".png").unwrap_or(file);
            job.image(name)
                .map(|bytes| Reply::bytes("image/png", bytes))
                .ok_or_else(|| {
                    let status = job.status();
                    ViewerError::NotFound(format!(
                        "render {}: no image {file} (state {:?}; images {:?})",
                        job.id, status.state, status.images
                    ))
                })
        }
        (_, ["api", ..]) | (_, [""]) | (_, ["index.html" | "viewer.js" | "viewer.css"]) => Err(
            ViewerError::NotFound(format!("{method} {path}: no such endpoint")),
        ),
        _ => Err(ViewerError::NotFound(format!("{path}: not found"))),
    }
}

fn parse<T: serde::de::DeserializeOwned>(body: &[u8]) -> Result<T, ViewerError> {
    serde_json::from_slice(body)
        .map_err(|e| ViewerError::BadRequest(format!("request body: invalid JSON: {e}")))
}

fn job(jobs: &Jobs, id: &str) -> Result<std::sync::Arc<crate::jobs::Job>, ViewerError> {
    let n: u64 = id
        .parse()
        .map_err(|_| ViewerError::BadRequest(format!("render job {id:?}: not a number")))?;
    jobs.get(n)
        .ok_or_else(|| ViewerError::NotFound(format!("render job {n}: none (or no longer kept)")))
}

/// `/api/summary`.
pub fn summary(viewer: &Viewer) -> Value {
    let d = &viewer.data;
    let field = viewer.field();
    let b = &d.meta.scene_box;
    let text = d.options.text_model.is_some();
    json!({
        "run": d.run_name(),
        "training": d.options.training,
        "field_version": field.version,
        "iteration": field.iteration,
        "points": d.points.len(),
        "point_source": d.points.source.name(),
        "has_truth": d.points.has_truth(),
        "has_uncertainty": d.points.has_uncertainty(),
        "has_text_model": text,
        "feature_dim": d.meta.feature_dim,
        "box": { "min": b.min, "max": b.max },
        "default_negatives": if text { CANONICAL_NEGATIVES } else { "" },
    })
}

/// `/api/classes`: names and the colours of `eval segment`'s PLYs.
pub fn classes(viewer: &Viewer) -> Value {
    let names = viewer
        .data
        .classes
        .as_ref()
        .map(|c| c.names.clone())
        .unwrap_or_default();
    let list: Vec<Value> = names
        .iter()
        .enumerate()
        .map(|(i, n)| json!({ "id": i, "name": n, "color": class_color(i) }))
        .collect();
    json!({ "classes": list })
}

/// `/api/cameras`.
pub fn cameras(viewer: &Viewer) -> Value {
    let list: Vec<Value> = viewer
        .data
        .cameras
        .iter()
        .map(|c| {
            let (k, p) = (&c.camera.intrinsics, &c.camera.pose);
            json!({
                "name": c.name, "kind": c.kind,
                "width": k.width, "height": k.height,
                "fx": k.fx, "fy": k.fy, "cx": k.cx, "cy": k.cy,
                "rotation": p.rotation.concat(),
                "position": p.translation,
            })
        })
        .collect();
    json!({ "cameras": list })
}

/// `/api/curve`: the training lines of `metrics.jsonl` (lines that do not
/// parse, e.g. one being written, are skipped).
pub fn curve(viewer: &Viewer) -> Value {
    let text = std::fs::read_to_string(viewer.data.run.metrics()).unwrap_or_default();
    let num = |v: &Value, k: &str| v.get(k).and_then(Value::as_f64).filter(|x| x.is_finite());
    let points: Vec<Value> = text
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|v| v.get("event").and_then(Value::as_str) == Some("train"))
        .map(|v| json!({ "iteration": num(&v, "iteration"), "loss": num(&v, "loss"), "psnr": num(&v, "psnr") }))
        .collect();
    json!({ "points": points })
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ExportRequest {
    #[serde(default)]
    positives: String,
    #[serde(default)]
    negatives: String,
    #[serde(default = "half")]
    threshold: f32,
}

fn half() -> f32 {
    0.5
}

/// `/api/export`: the points at or above the threshold as a binary PLY
/// with their colours and a `relevancy` property.
fn export(viewer: &Viewer, body: &[u8]) -> Result<Reply, ViewerError> {
    let req: ExportRequest = parse(body)?;
    if !(0.0..=1.0).contains(&req.threshold) {
        return Err(ViewerError::BadRequest(format!(
            "threshold {} is outside [0, 1]",
            req.threshold
        )));
    }
    let q = QueryRequest {
        positives: req.positives,
        negatives: req.negatives,
    };
    let r = query_points(viewer, &q)?;
    let pts = &viewer.data.points;
    let keep: Vec<usize> = (0..pts.len())
        .filter(|&i| r.values[i] >= req.threshold)
        .collect();
    let mut out = Vec::new();
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment relevancy of \"{}\" (threshold {})\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         property float relevancy\nend_header\n",
        r.positives.join(";").replace(['\n', '"'], " "),
        req.threshold,
        keep.len()
    );
    out.write_all(header.as_bytes()).ok();
    for &i in &keep {
        for x in pts.positions[i] {
            out.extend_from_slice(&(x as f32).to_le_bytes());
        }
        out.extend_from_slice(&pts.colours[i]);
        out.extend_from_slice(&r.values[i].to_le_bytes());
    }
    let label = field_ops::text_query::label(&r.positives.join("_"));
    Ok(Reply {
        status: 200,
        content_type: "application/octet-stream",
        body: out,
        filename: Some(format!("{label}.ply")),
    })
}
