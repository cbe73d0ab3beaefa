//! The run directory the eval integration tests share: an untrained tiny
//! field on the synthetic CI scene (seed 0), which loads, renders and
//! segments like a trained one.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use burn::module::Module;
use burn::tensor::Device;
use datasets::SceneMeta;
use datasets::synthetic::{SceneSize, generate};
use model::{FeatureHeadConfig, MipMlpConfig, OpenNerfConfig};

/// The tiny field: a 2 x 16 trunk, a one-layer head to `dim` channels,
/// 4 + 4 samples a ray.
pub fn tiny_config(dim: usize) -> OpenNerfConfig {
    OpenNerfConfig::new(FeatureHeadConfig::new(dim).with_width(8).with_layers(1))
        .with_mlp(
            MipMlpConfig::new()
                .with_width(16)
                .with_depth(2)
                .with_skip_layer(1)
                .with_max_deg(4),
        )
        .with_num_samples(4)
}

/// Writes `model.bpk`, `config.json`, `scene.json` and `split.json` (frame 0
/// held out) of the tiny run into `dir`.
// Not every test binary that shares this module uses the room's run.
#[allow(dead_code)]
pub fn write_tiny_run(dir: &Path) {
    write_run(dir, SceneSize::Ci, |config| config);
}

/// The tiny run of the synthetic outdoor scene with an unbounded field (its
/// ball around the scene box, as `train` makes it) and the proposal sampler (rounds of 8 and 8
/// samples of a 1 x 8 proposal MLP).
// Not every test binary that shares this module renders unbounded runs.
#[allow(dead_code)]
pub fn write_tiny_unbounded_run(dir: &Path) {
    let scene = generate(0, SceneSize::Outdoor).expect("outdoor scene");
    let corner = scene.scene_box.normalize_point(scene.scene_box.max);
    let radius = corner.iter().map(|v| v * v).sum::<f64>().sqrt();
    write_run(dir, SceneSize::Outdoor, |config| {
        config
            .with_unbounded(Some(model::UnboundedConfig::new(radius as f32)))
            .with_proposal(Some(
                model::ProposalConfig::new()
                    .with_samples(vec![8, 8])
                    .with_depth(1)
                    .with_width(8),
            ))
    });
}

/// The tiny run of the synthetic scene of `size` (seed 0), its field
/// configured by `configure`, written into `dir`.
fn write_run(dir: &Path, size: SceneSize, configure: impl Fn(OpenNerfConfig) -> OpenNerfConfig) {
    let scene = generate(0, size).expect("synthetic scene");
    let features = scene.features.as_ref().expect("features");
    let config = configure(tiny_config(features.dim()));
    let bytes = config
        .init(&Device::flex())
        .into_record()
        .into_bytes()
        .expect("serialise");
    std::fs::write(dir.join("model.bpk"), bytes.to_vec()).expect("weights");
    let json = |name: &str, v: serde_json::Value| {
        std::fs::write(dir.join(name), v.to_string()).expect("write json");
    };
    json("config.json", serde_json::json!({ "model": config }));
    let meta = SceneMeta {
        source: scene.source.clone(),
        scene_box: scene.scene_box,
        background: scene.background,
        pca: features.pca.clone(),
        feature_dim: Some(features.full_dim),
        world: None,
    };
    json("scene.json", serde_json::to_value(&meta).expect("meta"));
    let n = scene.frames.len();
    json(
        "split.json",
        serde_json::json!({ "train": (1..n).collect::<Vec<_>>(), "heldout": [0] }),
    );
}

/// Rewrites the tiny run's weights in `dir` so that its field is empty
/// everywhere (the density layer's weights and bias -50: density about
/// `softplus(-51)` whatever the trunk gives): every camera there is free
/// and sees every point, so proposals are never rejected by the field.
// Not every test binary that shares this module proposes novel views.
#[allow(dead_code)]
pub fn make_field_empty(dir: &Path) {
    use burn::nn::{Initializer, LinearConfig};
    let scene = generate(0, SceneSize::Ci).expect("CI scene");
    let dim = scene.features.as_ref().expect("features").dim();
    let device = Device::flex();
    let mut model = tiny_config(dim).init(&device);
    let mlp = model.mlp.as_mut().expect("the Mip-NeRF field");
    let [width, out] = mlp.density.weight.dims();
    mlp.density = LinearConfig::new(width, out)
        .with_initializer(Initializer::Constant { value: -50.0 })
        .init(&device);
    let bytes = model.into_record().into_bytes().expect("serialise");
    std::fs::write(dir.join("model.bpk"), bytes.to_vec()).expect("weights");
}

/// `eval view` on `run` with a free port; returns the child and the page's
/// address once it is printed.
#[allow(dead_code)]
pub fn start_view(run: &Path, seconds: &str) -> (Child, String, mpsc::Receiver<String>) {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_eval"))
        .args(["view", "--run", run.to_str().expect("utf-8"), "--port", "0"])
        .args(["--seconds", seconds])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("eval view starts");
    let stdout = child.stdout.take().expect("stdout");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    loop {
        let Ok(line) = rx.recv_timeout(Duration::from_secs(180)) else {
            let _ = child.kill();
            let _ = child.wait();
            panic!("eval view did not print its address");
        };
        if let Some(url) = line.strip_prefix("viewer at ") {
            return (child, url.trim().to_string(), rx);
        }
    }
}

/// The lines printed after the address, up to the end of the output: the
/// reader thread may still hold the last lines when the process has
/// exited, so wait for it to close the channel (at most 30 s a line).
#[allow(dead_code)]
pub fn printed_until_closed(rx: &mpsc::Receiver<String>) -> Vec<String> {
    let mut lines = Vec::new();
    while let Ok(line) = rx.recv_timeout(Duration::from_secs(30)) {
        lines.push(line);
    }
    lines
}

#[allow(dead_code)]
pub fn get(url: &str, path: &str) -> String {
    let addr = url.trim_start_matches("http://").trim_end_matches('/');
    let mut s = TcpStream::connect(addr).expect("connect");
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: t\r\nConnection: close\r\n\r\n"
    )
    .expect("send");
    // The reply's body may be binary (the points): read bytes.
    let mut out = Vec::new();
    s.read_to_end(&mut out).expect("read");
    String::from_utf8_lossy(&out).into_owned()
}
