//! `eval view`: serves the run's web viewer (see the `viewer` crate) until
//! Ctrl-C, `--seconds` or the run directory's removal.

use std::net::IpAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;

use crate::checks::{invalid, radius};
use field_ops::OpsError;
use field_ops::backend::BackendArgs;
use field_ops::run_dir::{RunDir, load_run, rebuild_scene};
use viewer::{ServerOptions, Viewer, ViewerData, ViewerOptions};

/// Arguments of `view`.
#[derive(Debug, Clone, clap::Args)]
pub struct ViewArgs {
    /// Run directory.
    #[arg(long)]
    pub run: PathBuf,
    /// Port to serve the page on (0: any free port).
    #[arg(long, default_value_t = 7007)]
    pub port: u16,
    /// Address to listen on: 127.0.0.1 keeps the page on this machine (reach
    /// it from a laptop with the printed `ssh -L` line); 0.0.0.0 opens it to
    /// every network interface (a warning is printed).
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// CLIP text model directory (Hugging Face or OpenCLIP layout, as for
    /// `eval query`) that embeds free text typed in the page; without it
    /// the text box takes class names only. It must be the CLIP model whose
    /// image features the field was trained on [default: the run's --vlm
    /// model, if it was trained with one].
    #[arg(long, value_name = "DIR")]
    pub text_model: Option<PathBuf>,
    /// Classes of the legend and the class colours, comma-separated free
    /// text embedded by --text-model, for scenes without classes of their
    /// own (a capture) or to replace them.
    #[arg(long)]
    pub classes: Option<String>,
    /// Points sent to the page at most (the cloud is thinned evenly).
    #[arg(long, default_value_t = 200_000)]
    pub max_points: usize,
    /// Largest width or height of a render the page may ask for, pixels.
    #[arg(long, default_value_t = 640)]
    pub max_render_side: u32,
    /// Radius (metres) of the Gaussian a point is queried with.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    pub radius: f64,
    /// Rays or points per forward pass.
    #[arg(long, default_value_t = 4096)]
    pub chunk: usize,
    /// Stop after this many seconds [default: serve until Ctrl-C].
    #[arg(long, allow_negative_numbers = true)]
    pub seconds: Option<f64>,
    /// Compute backend and device.
    #[command(flatten)]
    pub compute: BackendArgs,
}

/// Checks `view`'s flags before anything is loaded.
pub fn check(a: &ViewArgs) -> Result<IpAddr, OpsError> {
    a.compute.check().map_err(OpsError::Invalid)?;
    radius(a.radius)?;
    for (flag, v) in [("max-points", a.max_points), ("chunk", a.chunk)] {
        if v == 0 {
            return Err(invalid(format!("--{flag} 0: must be at least 1")));
        }
    }
    if !(16..=4096).contains(&a.max_render_side) {
        return Err(invalid(format!(
            "--max-render-side {}: must be between 16 and 4096 pixels",
            a.max_render_side
        )));
    }
    if let Some(s) = a.seconds
        && !(s.is_finite() && s > 0.0)
    {
        return Err(invalid(format!("--seconds {s}: must be a positive number")));
    }
    if let Some(dir) = &a.text_model
        && !dir.is_dir()
    {
        return Err(invalid(format!(
            "--text-model {}: not a directory",
            dir.display()
        )));
    }
    a.host.parse::<IpAddr>().map_err(|_| {
        invalid(format!(
            "--host {:?}: not an IP address (127.0.0.1 for this machine only, 0.0.0.0 for every \
             interface)",
            a.host
        ))
    })
}

/// Runs `view`: loads the run, serves the page and blocks until stopped;
/// returns why it stopped.
pub fn view_command(args: &ViewArgs) -> Result<String, OpsError> {
    let host = check(args)?;
    let device = args.compute.device();
    let mut run = load_run(&args.run, &device)?;
    let dir = RunDir::new(&args.run);
    let rebuilt = rebuild_scene(&dir, &run.meta)?;
    let novel = rebuilt.novel.map(|n| n.frames).unwrap_or_default();
    run.split.train.extend(&novel);
    run.split.check(rebuilt.scene.frames.len(), &dir.split())?;
    let scene = rebuilt.scene;
    let text_model = crate::text_query::default_text_model(args.text_model.as_deref(), &run.meta);
    let classes = match &args.classes {
        Some(list) => {
            let names = crate::text_query::parse_classes(list)?;
            let model =
                crate::text_query::model_for(text_model.as_deref(), &run.meta, "--classes")?;
            Some(crate::text_query::embed(
                &model, &names, &args.run, &run.meta, &device,
            )?)
        }
        None => scene.classes.clone(),
    };
    let options = ViewerOptions {
        max_points: args.max_points,
        chunk: args.chunk,
        radius: args.radius,
        text_model,
        training: false,
        max_render_side: args.max_render_side,
    };
    let busy = field_ops::progress::spinner("preparing the viewer's points".into());
    let data = ViewerData::build(
        dir, run.meta, &scene, &run.split, &novel, classes, &run.model, options,
    )?;
    // The iterations the weights were trained for, when the run finished.
    let iteration = field_ops::json::read_json::<serde_json::Value>(&run.dir.summary())
        .ok()
        .and_then(|v| v["iterations"].as_u64())
        .map(|i| i as usize);
    let viewer = Arc::new(Viewer::new(data, run.model, iteration, device));
    // The points' classes are computed before the page asks for them.
    viewer.point_features();
    busy.finish_and_clear();
    let opts = ServerOptions {
        host: host.to_string(),
        port: args.port,
        threads: 4,
    };
    let handle = viewer::start(viewer.clone(), &opts).map_err(|e| invalid(e.to_string()))?;
    println!(
        "{} points ({}), {} cameras",
        viewer.data.points.len(),
        viewer.data.points.source.name(),
        viewer.data.cameras.len()
    );
    for line in viewer::http::access_lines(&handle.addr) {
        println!("{line}");
    }
    let flag = handle.stop_flag();
    let on_signal = flag.clone();
    if let Err(e) = ctrlc::set_handler(move || on_signal.store(true, Ordering::Relaxed)) {
        eprintln!("warning: Ctrl-C cannot stop the viewer cleanly ({e}); it will end the process");
    }
    if let Some(s) = args.seconds {
        let timer = flag.clone();
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_secs_f64(s));
            timer.store(true, Ordering::Relaxed);
        });
    }
    Ok(handle.wait())
}
