//! `train --viewer`: the run's web page served from the training process,
//! its field replaced by the current weights every few seconds.

use std::sync::Arc;
use std::time::{Duration, Instant};

use burn::module::Module;
use burn::tensor::Device;
use datasets::{Scene, SceneMeta};
use field_ops::json::read_json;
use field_ops::run_dir::{RunDir, Split};
use model::OpenNerf;
use viewer::{ServerHandle, ServerOptions, Viewer, ViewerData, ViewerOptions};

use crate::error::TrainError;

/// Where and how often the training process serves its viewer.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewerSettings {
    /// Address to listen on.
    pub host: String,
    /// Port (0: any free port).
    pub port: u16,
    /// Seconds between publishing the current field to the page.
    pub every: f64,
}

/// The viewer of a training session.
pub(super) struct LiveViewer {
    viewer: Arc<Viewer>,
    handle: ServerHandle,
    every: Duration,
    last: Instant,
}

impl LiveViewer {
    /// Starts the viewer of `run` on `scene` with the session's first field.
    pub(super) fn start(
        settings: &ViewerSettings,
        scene: &Scene,
        split: &Split,
        run: &RunDir,
        model: &OpenNerf,
        iteration: usize,
        device: &Device,
    ) -> Result<Self, TrainError> {
        let meta: SceneMeta = read_json(&run.scene())?;
        let options = ViewerOptions {
            training: true,
            // A --vlm run's own model embeds the page's free text.
            text_model: field_ops::text_query::default_text_model(None, &meta),
            ..ViewerOptions::default()
        };
        let field = model.valid();
        let data = ViewerData::build(
            run.clone(),
            meta,
            scene,
            split,
            &[],
            scene.classes.clone(),
            &field,
            options,
        )?;
        let viewer = Arc::new(Viewer::new(data, field, Some(iteration), device.clone()));
        let opts = ServerOptions {
            host: settings.host.clone(),
            port: settings.port,
            threads: 4,
        };
        let handle = viewer::start(viewer.clone(), &opts)
            .map_err(|e| TrainError::Config(format!("--viewer: {e}")))?;
        for line in viewer::http::access_lines(&handle.addr) {
            eprintln!("{line}");
        }
        Ok(Self {
            viewer,
            handle,
            every: Duration::from_secs_f64(settings.every),
            last: Instant::now(),
        })
    }

    /// Publishes `model` (after iteration `it`) when the last one is old enough.
    pub(super) fn refresh(&mut self, model: &OpenNerf, it: usize) {
        if self.last.elapsed() >= self.every {
            self.viewer.publish(model.valid(), it);
            self.last = Instant::now();
        }
    }

    /// Stops serving at the end of the session.
    pub(super) fn stop(mut self) {
        let why = self.handle.shutdown();
        eprintln!("viewer {why} with the training; `eval view --run DIR` serves the finished run");
    }
}
