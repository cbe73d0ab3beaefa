//! The novel views in the loop: made when due (which changes the scene
//! the session trains on) and joined to the sampler's draw from the
//! iteration recorded with them.

use burn::module::Module;
use model::OpenNerf;

use super::TrainLoop;
use crate::batch::TrainSampler;
use crate::error::TrainError;
use crate::metrics_log::MetricsEvent;
use crate::progress::say;
use crate::training::novel::{add_views, added_message, adding_message, log_line};

impl TrainLoop<'_> {
    /// Makes the novel views when they are due before iteration `it`.
    pub(super) fn add_novel_views_if_due(
        &mut self,
        model: &OpenNerf,
        it: usize,
    ) -> Result<(), TrainError> {
        if !self.views.due(&self.config, it) {
            return Ok(());
        }
        say(&self.bar, adding_message(&self.config, it));
        let bar = &self.bar;
        let (scene, stages) = (&mut self.scene, &mut self.stages);
        let report = stages.run("novel views", || {
            add_views(
                &model.valid(),
                scene.to_mut(),
                &self.split.train,
                &self.config,
                self.run,
                it,
                &self.inference,
                |done, total| bar.set_message(format!("novel view {done}/{total} rendered")),
            )
        })?;
        let line = log_line(&report, it, self.clock.wall());
        self.log.write(&MetricsEvent::NovelViews(line))?;
        say(&self.bar, added_message(&report, self.run, it));
        self.views.added = Some(report.added);
        self.stepper.forget_ahead();
        Ok(())
    }

    /// From the iteration recorded with the novel views on, the sampler
    /// draws from them too.
    pub(super) fn join_novel_views(&mut self, it: usize) -> Result<(), TrainError> {
        if self.views.join(it) {
            let novel = self.views.novel_frames(it);
            let (scene, config, train) = (&self.scene, &self.config, &self.split.train);
            let sampler = self.stages.run("sampler", || {
                TrainSampler::with_novel(scene, train, novel, &config.sampler, self.state.seed)
            })?;
            self.stepper.set_sampler(sampler);
        }
        Ok(())
    }
}
