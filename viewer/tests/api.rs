//! The viewer's HTTP API against a tiny run on the synthetic CI scene:
//! every endpoint, its answers checked against independent computations,
//! and bad requests (JSON, classes, paths, sizes, concurrency, cancels).

mod common;

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::Arc;
use std::time::{Duration, Instant};

use burn::tensor::Device;
use datasets::synthetic::{SceneSize, generate};
use datasets::{Scene, SceneMeta};
use field_ops::render::{ViewSettings, render_view};
use field_ops::run_dir::{RunDir, Split};
use field_ops::sample::sampled_features;
use viewer::{ServerHandle, ServerOptions, Viewer, ViewerData, ViewerOptions};

struct Served {
    handle: ServerHandle,
    viewer: Arc<Viewer>,
    scene: Scene,
    _dir: tempfile::TempDir,
}

/// The backend's random generator is one for the process, shared by the
/// tests running beside each other: seeding and drawing under one lock keeps
/// another test's seed from landing between them.
static DRAW: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A tiny field drawn from `seed`: the served field takes 1 and the field
/// a test publishes 2, so that they differ on every run.
fn seeded_tiny_model(dim: usize, device: &Device, seed: u64) -> model::OpenNerf {
    let _held = DRAW
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    device.seed(seed);
    common::tiny_model(dim, device)
}

/// An untrained tiny field on the CI scene, served on a free port; `chunk`
/// rays a forward pass (small: renders take many chunks).
fn serve(chunk: usize) -> Served {
    let dir = tempfile::tempdir().expect("temp dir");
    let scene = generate(0, SceneSize::Ci).expect("CI scene");
    let features = scene.features.as_ref().expect("features");
    let device = Device::flex();
    let model = seeded_tiny_model(features.dim(), &device, 1);
    let meta = SceneMeta {
        source: scene.source.clone(),
        scene_box: scene.scene_box,
        background: scene.background,
        pca: features.pca.clone(),
        feature_dim: Some(features.full_dim),
        world: None,
    };
    let n = scene.frames.len();
    let split = Split {
        train: (1..n).collect(),
        heldout: vec![0],
    };
    let options = ViewerOptions {
        chunk,
        ..ViewerOptions::default()
    };
    let data = ViewerData::build(
        RunDir::new(dir.path()),
        meta,
        &scene,
        &split,
        &[],
        scene.classes.clone(),
        &model,
        options,
    )
    .expect("viewer data");
    let viewer = Arc::new(Viewer::new(data, model, None, device));
    let opts = ServerOptions {
        port: 0,
        ..ServerOptions::default()
    };
    let handle = viewer::start(viewer.clone(), &opts).expect("server starts");
    Served {
        handle,
        viewer,
        scene,
        _dir: dir,
    }
}

/// One HTTP/1.1 request; returns status, content type and body.
fn call(addr: SocketAddr, method: &str, path: &str, body: &[u8]) -> (u16, String, Vec<u8>) {
    let mut s = TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(120))).ok();
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: test\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    // A server refusing an oversized body may close before it is all sent.
    let _ = s.write_all(head.as_bytes()).and_then(|_| s.write_all(body));
    let mut raw = Vec::new();
    let _ = s.read_to_end(&mut raw);
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a response head");
    let head = String::from_utf8_lossy(&raw[..split]).to_string();
    let status: u16 = head
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .expect("status");
    let content_type = head
        .lines()
        .find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.eq_ignore_ascii_case("content-type")
                .then(|| v.trim().to_string())
        })
        .unwrap_or_default();
    (status, content_type, raw[split + 4..].to_vec())
}

fn json(addr: SocketAddr, method: &str, path: &str, body: &str) -> (u16, serde_json::Value) {
    let (status, _, b) = call(addr, method, path, body.as_bytes());
    let v = serde_json::from_slice(&b).unwrap_or_else(|e| {
        panic!(
            "{method} {path}: not JSON ({e}): {}",
            String::from_utf8_lossy(&b)
        )
    });
    (status, v)
}

/// Cosine of every point's lifted feature (mean + B^T c, in f64) with `e`.
fn brute_cosines(v: &Viewer, e: &[f32]) -> Vec<f64> {
    let d = &v.data;
    let f = sampled_features(
        &v.field().model,
        &d.points.positions,
        &d.meta.scene_box,
        d.options.radius,
        d.options.chunk,
        &v.device,
    );
    let en = e.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
    let k = d.meta.pca.as_ref().map_or(e.len(), |p| p.k);
    f.chunks(k)
        .map(|c| {
            // Lifted out of the PCA space when the run compresses features.
            let full: Vec<f64> = match d.meta.pca.as_ref() {
                None => c.iter().map(|&x| x as f64).collect(),
                Some(pca) => (0..pca.dim)
                    .map(|j| {
                        pca.mean[j] as f64
                            + (0..pca.k)
                                .map(|i| c[i] as f64 * pca.components[i * pca.dim + j] as f64)
                                .sum::<f64>()
                    })
                    .collect(),
            };
            let n = full.iter().map(|x| x * x).sum::<f64>().sqrt();
            full.iter().zip(e).map(|(a, &b)| a * b as f64).sum::<f64>() / (n * en)
        })
        .collect()
}

#[test]
fn page_summary_classes_cameras_and_points_match_the_run() {
    let s = serve(4096);
    let addr = s.handle.addr;
    let (status, ty, page) = call(addr, "GET", "/", b"");
    assert_eq!(status, 200);
    assert!(ty.starts_with("text/html"), "{ty}");
    assert!(String::from_utf8_lossy(&page).contains("viewer.js"));
    for (path, ty) in [
        ("/viewer.js", "text/javascript"),
        ("/viewer.css", "text/css"),
    ] {
        let (status, got, body) = call(addr, "GET", path, b"");
        assert_eq!((status, got.starts_with(ty)), (200, true), "{path}: {got}");
        assert!(!body.is_empty());
    }
    let classes = s.scene.classes.as_ref().expect("classes");
    let cloud = s.scene.points.as_ref().expect("cloud");
    let n = cloud.positions.len();
    let (status, sum) = json(addr, "GET", "/api/summary", "");
    assert_eq!(status, 200);
    assert_eq!(sum["points"], n);
    assert_eq!(sum["point_source"], "labelled cloud");
    assert_eq!(sum["has_truth"], true);
    assert_eq!(sum["has_text_model"], false);
    assert_eq!(sum["default_negatives"], "");
    let (_, cl) = json(addr, "GET", "/api/classes", "");
    let list = cl["classes"].as_array().expect("list");
    assert_eq!(list.len(), classes.names.len());
    assert_eq!(list[2]["name"], classes.names[2].as_str());
    let (_, cams) = json(addr, "GET", "/api/cameras", "");
    let cams = cams["cameras"].as_array().expect("cameras");
    assert_eq!(cams.len(), s.scene.frames.len());
    assert_eq!(cams[0]["kind"], "heldout");
    assert_eq!(cams[1]["kind"], "train");
    let pose = &s.scene.frames[1].camera.pose;
    assert_eq!(cams[1]["rotation"][5].as_f64(), Some(pose.rotation[1][2]));
    assert_eq!(cams[1]["position"][0].as_f64(), Some(pose.translation[0]));

    let (status, ty, b) = call(addr, "GET", "/api/points", b"");
    assert_eq!((status, ty.as_str()), (200, "application/octet-stream"));
    assert_eq!(b.len(), 16 + 24 * n);
    assert_eq!(&b[..4], b"ONPT");
    let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().expect("4 bytes"));
    let f32_at = |o: usize| f32::from_le_bytes(b[o..o + 4].try_into().expect("4 bytes"));
    let u16_at = |o: usize| u16::from_le_bytes(b[o..o + 2].try_into().expect("2 bytes"));
    assert_eq!((u32_at(4), u32_at(8) as usize), (1, n));
    let i = n / 2;
    assert_eq!(f32_at(16 + 12 * i + 4), cloud.positions[i][1] as f32);
    let colours = cloud.colors.as_ref().expect("colours");
    assert_eq!(&b[16 + 12 * n + 4 * i..][..3], &colours[i]);
    let truth = cloud.labels.as_ref().expect("labels");
    assert_eq!(u16_at(16 + 18 * n + 2 * i) as i64, truth[i]);
    // Predicted classes: the highest cosine in the full space, by brute force.
    let cos: Vec<Vec<f64>> = (0..classes.names.len())
        .map(|c| {
            brute_cosines(
                &s.viewer,
                &classes.data[c * classes.dim..(c + 1) * classes.dim],
            )
        })
        .collect();
    let mut agree = 0;
    for p in 0..n {
        let best = (0..cos.len())
            .max_by(|&a, &b| cos[a][p].total_cmp(&cos[b][p]))
            .expect("classes");
        agree += usize::from(u16_at(16 + 16 * n + 2 * p) as usize == best);
    }
    // Ties within rounding may go either way; nothing else may differ.
    assert!(agree * 1000 >= n * 999, "{agree} of {n}");
    assert!(f32_at(16 + 20 * n).is_nan(), "no uncertainty was computed");
}

#[test]
fn queries_score_points_like_a_brute_force_cosine_and_refuse_bad_requests() {
    let s = serve(4096);
    let addr = s.handle.addr;
    let classes = s.scene.classes.as_ref().expect("classes");
    let name = &classes.names[1];
    let body = format!(r#"{{"positives": "{}"}}"#, name.to_uppercase());
    let (status, q) = json(addr, "POST", "/api/query", &body);
    assert_eq!(status, 200, "{q}");
    assert_eq!(q["quantity"], "cosine");
    let values: Vec<f64> = q["values"]
        .as_array()
        .expect("values")
        .iter()
        .map(|v| v.as_f64().expect("number"))
        .collect();
    let cos = brute_cosines(&s.viewer, &classes.data[classes.dim..2 * classes.dim]);
    let (lo, hi) = (q["lo"].as_f64().expect("lo"), q["hi"].as_f64().expect("hi"));
    let lo_ref = cos.iter().copied().fold(f64::INFINITY, f64::min);
    let hi_ref = cos.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert!(
        (lo - lo_ref).abs() < 1e-4 && (hi - hi_ref).abs() < 1e-4,
        "{lo} {hi}"
    );
    for (v, c) in values.iter().zip(&cos) {
        assert!(
            (v - (c - lo_ref) / (hi_ref - lo_ref)).abs() < 1e-3,
            "{v} vs {c}"
        );
    }
    let cut = q["cut"].as_f64().expect("cut");
    assert!((cut - (lo + 0.5 * (hi - lo))).abs() < 1e-9);
    // With negatives: LERF's relevancy, a number in (0, 1) before scaling.
    let body = format!(
        r#"{{"positives": "{name}", "negatives": "{}"}}"#,
        classes.names[0]
    );
    let (status, q) = json(addr, "POST", "/api/query", &body);
    assert_eq!(
        (status, q["quantity"].as_str()),
        (200, Some("relevancy")),
        "{q}"
    );
    assert!(q["lo"].as_f64().expect("lo") > 0.0 && q["hi"].as_f64().expect("hi") < 1.0);

    for (body, says) in [
        (r#"{"positives": "spaceship"}"#, "not a class of this run"),
        (r#"{"positives": ""}"#, "give a class name"),
        (r#"{"positives": "#, "invalid JSON"),
        (r#"{"positive": "chair"}"#, "unknown field"),
        (r#"{"positives": 3}"#, "invalid JSON"),
    ] {
        let (status, e) = json(addr, "POST", "/api/query", body);
        assert_eq!(status, 400, "{body}: {e}");
        assert!(
            e["error"].as_str().expect("error").contains(says),
            "{body}: {e}"
        );
    }
}

#[test]
fn paths_outside_the_page_unknown_routes_and_oversized_bodies_are_refused() {
    let s = serve(4096);
    let addr = s.handle.addr;
    for path in [
        "/../config.json",
        "/api/../../etc/passwd",
        "/%2e%2e/model.bpk",
        "/viewer.js/../../split.json",
    ] {
        let (status, _, body) = call(addr, "GET", path, b"");
        assert_eq!(status, 400, "{path}");
        assert!(String::from_utf8_lossy(&body).contains("refused"), "{path}");
    }
    for (method, path) in [
        ("GET", "/config.json"),
        ("GET", "/api/nothing"),
        ("PUT", "/api/query"),
    ] {
        let (status, e) = json(addr, method, path, "");
        assert_eq!(status, 404, "{method} {path}: {e}");
    }
    let big = format!(r#"{{"positives": "{}"}}"#, "a".repeat(100_000));
    let (status, e) = json(addr, "POST", "/api/query", &big);
    assert_eq!(status, 413, "{e}");
    let (status, e) = json(addr, "GET", "/api/render/abc", "");
    assert_eq!(status, 400, "{e}");
    let (status, e) = json(addr, "GET", "/api/render/99", "");
    assert_eq!(status, 404, "{e}");
}

#[test]
fn sixteen_concurrent_requests_are_all_answered() {
    let s = serve(4096);
    let addr = s.handle.addr;
    let name = s.scene.classes.as_ref().expect("classes").names[0].clone();
    let threads: Vec<_> = (0..16)
        .map(|i| {
            let name = name.clone();
            std::thread::spawn(move || match i % 3 {
                0 => call(addr, "GET", "/api/summary", b"").0,
                1 => call(addr, "GET", "/api/points", b"").0,
                _ => {
                    call(
                        addr,
                        "POST",
                        "/api/query",
                        format!(r#"{{"positives":"{name}"}}"#).as_bytes(),
                    )
                    .0
                }
            })
        })
        .collect();
    for t in threads {
        assert_eq!(t.join().expect("thread"), 200);
    }
}

fn camera_body(s: &Served, frame: usize, width: u32, query: Option<&str>) -> String {
    let c = &s.scene.frames[frame].camera;
    let h = (c.intrinsics.height as f64 * width as f64 / c.intrinsics.width as f64).round() as u32;
    let c = c.scaled(width, h);
    let k = &c.intrinsics;
    let q = query.map_or(String::new(), |q| {
        format!(r#", "query": {{"positives": "{q}"}}"#)
    });
    format!(
        r#"{{"camera": {{"rotation": {:?}, "position": {:?}, "width": {}, "height": {}, "fx": {}, "fy": {}, "cx": {}, "cy": {}}}{q}}}"#,
        c.pose.rotation.concat(),
        c.pose.translation,
        k.width,
        k.height,
        k.fx,
        k.fy,
        k.cx,
        k.cy
    )
}

fn wait_for(addr: SocketAddr, job: u64, states: &[&str]) -> serde_json::Value {
    let start = Instant::now();
    loop {
        let (_, st) = json(addr, "GET", &format!("/api/render/{job}"), "");
        if states.iter().any(|s| st["state"] == *s) {
            return st;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "{st}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn renders_equal_the_field_rendered_directly_and_can_be_cancelled() {
    let s = serve(64);
    let addr = s.handle.addr;
    let name = s.scene.classes.as_ref().expect("classes").names[1].clone();
    let (status, j) = json(
        addr,
        "POST",
        "/api/render",
        &camera_body(&s, 2, 48, Some(&name)),
    );
    assert_eq!(status, 202, "{j}");
    let job = j["job"].as_u64().expect("job");
    let st = wait_for(addr, job, &["done", "failed"]);
    assert_eq!(st["state"], "done", "{st}");
    assert_eq!(
        st["images"],
        serde_json::json!(["rgb", "depth", "opacity", "relevancy"])
    );
    // The depth image comes with its scale: what its colours stand for.
    let scale = &st["depth_scale"];
    assert_eq!(scale["quantity"], "depth", "{st}");
    assert_eq!(scale["units"], "m", "{st}");
    let (lo, hi) = (
        scale["lo"].as_f64().expect("lo"),
        scale["hi"].as_f64().expect("hi"),
    );
    assert!(lo.is_finite() && lo <= hi, "{st}");
    let caption = st["depth_caption"].as_str().expect("caption");
    assert!(
        caption.contains(" m (red, near) to ") && caption.contains(" m (blue, far)"),
        "{caption}"
    );
    let (status, ty, png) = call(addr, "GET", &format!("/api/render/{job}/rgb.png"), b"");
    assert_eq!((status, ty.as_str()), (200, "image/png"));
    let img = image::load_from_memory(&png).expect("png").to_rgb8();
    let cam = s.scene.frames[2].camera.scaled(48, 27);
    assert_eq!((img.width(), img.height()), (48, 27));
    let v = &s.viewer;
    let direct = render_view(
        &v.field().model,
        &cam,
        &v.data.meta.scene_box,
        &ViewSettings::new(v.data.meta.background, 64),
    )
    .expect("never cancelled without an observer");
    for (got, want) in img.as_raw().iter().zip(&direct.rgb) {
        assert!(
            (*got as f32 - want.clamp(0.0, 1.0) * 255.0).abs() <= 1.0,
            "{got} vs {want}"
        );
    }
    let (status, _, _) = call(addr, "GET", &format!("/api/render/{job}/normals.png"), b"");
    assert_eq!(status, 404);

    // A 640x360 render in 64-ray chunks (3600 of them) cancelled at once.
    let (_, j) = json(addr, "POST", "/api/render", &camera_body(&s, 3, 640, None));
    let big = j["job"].as_u64().expect("job");
    let (status, st) = json(addr, "DELETE", &format!("/api/render/{big}"), "");
    assert_eq!(status, 200, "{st}");
    let st = wait_for(addr, big, &["cancelled", "done", "failed"]);
    assert_eq!(st["state"], "cancelled", "{st}");
    assert!(st["progress"].as_f64().expect("progress") < 0.5, "{st}");
    // A new request cancels the one before it.
    let (_, a) = json(addr, "POST", "/api/render", &camera_body(&s, 3, 640, None));
    let (_, b) = json(addr, "POST", "/api/render", &camera_body(&s, 4, 32, None));
    let (a, b) = (a["job"].as_u64().expect("a"), b["job"].as_u64().expect("b"));
    assert_eq!(
        wait_for(addr, a, &["cancelled", "done"])["state"],
        "cancelled"
    );
    assert_eq!(wait_for(addr, b, &["done", "failed"])["state"], "done");

    for (body, says) in [
        (camera_body(&s, 2, 48, None).replace("\"width\": 48", "\"width\": 0"), "width 0"),
        (camera_body(&s, 2, 48, None).replace("\"width\": 48", "\"width\": 5000"), "width 5000"),
        (camera_body(&s, 2, 48, None).replace("\"rotation\": [", "\"rotation\": [2.0, "), "invalid JSON"),
        (r#"{"camera": {"rotation": [1,0,0,0,1,0,0,0,-1], "position": [0,0,0], "width": 8, "height": 8, "fx": 8, "fy": 8, "cx": 4, "cy": 4}}"#.to_string(), "not a rotation"),
    ] {
        let (status, e) = json(addr, "POST", "/api/render", &body);
        assert_eq!(status, 400, "{e}");
        assert!(e["error"].as_str().expect("error").contains(says), "{e}");
    }
}

#[test]
fn export_writes_the_points_above_the_threshold_and_the_curve_reads_the_log() {
    let s = serve(4096);
    let addr = s.handle.addr;
    let name = s.scene.classes.as_ref().expect("classes").names[1].clone();
    let (_, q) = json(
        addr,
        "POST",
        "/api/query",
        &format!(r#"{{"positives":"{name}"}}"#),
    );
    let above = q["values"]
        .as_array()
        .expect("values")
        .iter()
        .filter(|v| v.as_f64().expect("number") >= 0.7)
        .count();
    let body = format!(r#"{{"positives":"{name}","threshold":0.7}}"#);
    let (status, _, ply) = call(addr, "POST", "/api/export", body.as_bytes());
    assert_eq!(status, 200);
    let text = String::from_utf8_lossy(&ply);
    assert!(
        text.contains(&format!("element vertex {above}\n")),
        "{above}"
    );
    let header_end = text.find("end_header\n").expect("header") + "end_header\n".len();
    assert_eq!(ply.len() - header_end, above * 19);
    let (status, e) = json(
        addr,
        "POST",
        "/api/export",
        &format!(r#"{{"positives":"{name}","threshold":2}}"#),
    );
    assert_eq!(status, 400, "{e}");

    let metrics = s.viewer.data.run.metrics();
    std::fs::write(
        &metrics,
        "{\"event\":\"train\",\"iteration\":10,\"loss\":0.5,\"psnr\":12.5}\n\
         {\"event\":\"eval\",\"iteration\":10}\n{\"event\":\"train\",\"iteration\":20,\"lo",
    )
    .expect("metrics");
    let (_, c) = json(addr, "GET", "/api/curve", "");
    assert_eq!(
        c["points"],
        serde_json::json!([{"iteration": 10.0, "loss": 0.5, "psnr": 12.5}])
    );
}

#[test]
fn publishing_a_field_changes_the_version_and_the_predictions() {
    let s = serve(4096);
    let addr = s.handle.addr;
    let (_, a) = json(addr, "GET", "/api/summary", "");
    let (_, _, before) = call(addr, "GET", "/api/points", b"");
    let dim = s.scene.features.as_ref().expect("features").dim();
    s.viewer
        .publish(seeded_tiny_model(dim, &s.viewer.device, 2), 42);
    let (_, b) = json(addr, "GET", "/api/summary", "");
    assert_eq!(
        b["field_version"].as_u64(),
        a["field_version"].as_u64().map(|v| v + 1)
    );
    assert_eq!(b["iteration"], 42);
    let (_, _, after) = call(addr, "GET", "/api/points", b"");
    assert_eq!(u32::from_le_bytes(after[12..16].try_into().expect("4")), 2);
    let n = s.scene.points.as_ref().expect("cloud").positions.len();
    let preds = |b: &[u8]| b[16 + 16 * n..16 + 18 * n].to_vec();
    assert_ne!(
        preds(&before),
        preds(&after),
        "a new random field predicts other classes"
    );
}

#[test]
fn the_server_stops_when_the_run_directory_disappears() {
    let s = serve(4096);
    let dir = s.viewer.data.run.dir.clone();
    std::fs::remove_dir_all(&dir).expect("remove");
    let Served { handle, .. } = s;
    let start = Instant::now();
    let why = handle.wait();
    assert!(why.contains("is gone"), "{why}");
    assert!(start.elapsed() < Duration::from_secs(10));
}
