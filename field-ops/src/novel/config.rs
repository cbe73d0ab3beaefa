//! The settings of novel views: the `novel` key of a run's configuration.

use serde::{Deserialize, Serialize};

use super::oracle::NovelOracle;
use crate::uncertainty::Normalisation;

/// How novel cameras are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum NovelMode {
    /// No novel views.
    None,
    /// Views interpolated between consecutive training cameras.
    Trajectory,
    /// Cameras placed uniformly in the scene box, looking in random directions.
    Random,
    /// Cameras aimed at the points whose training features disagree most.
    #[default]
    Guided,
}

impl NovelMode {
    /// The mode's name on the command line and in records.
    pub fn name(self) -> &'static str {
        match self {
            NovelMode::None => "none",
            NovelMode::Trajectory => "trajectory",
            NovelMode::Random => "random",
            NovelMode::Guided => "guided",
        }
    }
}

impl std::fmt::Display for NovelMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Settings of the novel views (the `novel` key of a run's configuration).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct NovelViewConfig {
    /// Views added (0 = none).
    pub views: usize,
    /// Iteration they are added at (`None`: half-way through the schedule).
    pub after: Option<usize>,
    /// How the cameras are chosen.
    pub mode: NovelMode,
    /// Weight of the rendered depth in the depth loss (sensor depth has 1).
    pub depth_weight: f32,
    /// Rendered depth is kept only where the accumulated opacity reaches this.
    pub min_acc: f32,
    /// Views are rendered at this fraction of the first training frame's
    /// resolution (intrinsics scaled with it). Rendering costs the square of
    /// it; a close view resolves small objects at half the resolution still.
    pub scale: f64,
    /// Voxel size (metres) of the point cloud the uncertainty is measured on.
    pub voxel: f64,
    /// Distance of a guided camera from its target, metres.
    pub offset: f64,
    /// Guided targets closer than this to an accepted one are skipped, metres.
    pub min_separation: f64,
    /// Guided cameras whose render of their target differs from the colour
    /// the capture saw there by more than this (RMS, colours in [0, 1]) are
    /// rejected; `None` (`null` in JSON, the default): no check. See
    /// [`ProposalOptions::max_color_error`](super::guided::ProposalOptions::max_color_error).
    pub max_color_error: Option<f64>,
    /// External extractor for scenes on disk: program and leading arguments
    /// (see [`CommandExtractor`](datasets::extractor::CommandExtractor)); synthetic scenes use their own.
    pub extractor: Option<Vec<String>>,
    /// Ground truth in place of the field's render or the extractor's
    /// reading (synthetic scenes only; a diagnostic, see [`NovelOracle`]);
    /// `None` (the default): the method as specified.
    pub oracle: Option<NovelOracle>,
    /// How the uncertainty becomes each point's chance to be a guided
    /// target (a configuration without the key is read as `minmax-logdet`,
    /// what runs used before the choice existed).
    #[serde(default = "legacy_normalisation")]
    pub normalisation: Normalisation,
    /// Weight of the novel frames' colour in the colour loss (the captured
    /// frames have 1): the field's own render is no measurement, so 0 keeps
    /// it from reinforcing what the field already believes (a configuration
    /// without the key is read as 1, what runs used before).
    #[serde(default = "legacy_color_weight")]
    pub color_weight: f32,
    /// Feature-map cells of a novel view whose rendered opacity (the share
    /// of their pixels reaching `min_acc`) is below half carry no feature
    /// target: the extractor would read fog there (a configuration without
    /// the key is read as `false`, what runs did before).
    #[serde(default)]
    pub mask_features: bool,
}

fn legacy_normalisation() -> Normalisation {
    Normalisation::MinmaxLogdet
}

fn legacy_color_weight() -> f32 {
    1.0
}

impl Default for NovelViewConfig {
    fn default() -> Self {
        Self {
            views: 0,
            after: None,
            mode: NovelMode::Guided,
            depth_weight: 0.1,
            min_acc: 0.5,
            scale: 0.5,
            voxel: 0.1,
            offset: 0.5,
            min_separation: 0.5,
            max_color_error: None,
            extractor: None,
            oracle: None,
            normalisation: Normalisation::MinmaxLogdet,
            color_weight: 1.0,
            mask_features: true,
        }
    }
}

impl NovelViewConfig {
    /// Whether views are to be added at all.
    pub fn enabled(&self) -> bool {
        self.views > 0 && self.mode != NovelMode::None
    }

    /// Checks ranges; messages name the key.
    pub fn validate(&self) -> Result<(), String> {
        if self.views > 1000 {
            return Err(format!(
                "novel.views must be at most 1000, got {}",
                self.views
            ));
        }
        if self.after == Some(0) {
            return Err("novel.after must be at least 1 (the field must be trained first)".into());
        }
        if !(self.depth_weight.is_finite() && (0.0..=1.0).contains(&self.depth_weight)) {
            return Err(format!(
                "novel.depth_weight must be in [0, 1], got {}",
                self.depth_weight
            ));
        }
        if !(self.color_weight.is_finite() && (0.0..=1.0).contains(&self.color_weight)) {
            return Err(format!(
                "novel.color_weight must be in [0, 1], got {}",
                self.color_weight
            ));
        }
        if !(self.min_acc.is_finite() && (0.0..=1.0).contains(&self.min_acc)) {
            return Err(format!(
                "novel.min_acc must be in [0, 1], got {}",
                self.min_acc
            ));
        }
        if !(self.scale.is_finite() && self.scale > 0.0 && self.scale <= 1.0) {
            return Err(format!(
                "novel.scale must be in (0, 1] (a fraction of the capture resolution), got {}",
                self.scale
            ));
        }
        for (k, v) in [
            ("novel.voxel", self.voxel),
            ("novel.offset", self.offset),
            ("novel.min_separation", self.min_separation),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{k} must be a positive length in metres, got {v}"));
            }
        }
        if let Some(e) = self.max_color_error
            && !(e.is_finite() && e >= 0.0)
        {
            return Err(format!(
                "novel.max_color_error must be a non-negative colour difference or null, got {e}"
            ));
        }
        if let Some(cmd) = &self.extractor
            && cmd.first().is_none_or(|p| p.trim().is_empty())
        {
            return Err("novel.extractor must name a program".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_validation_names_the_key() {
        let ok = NovelViewConfig {
            views: 4,
            ..Default::default()
        };
        assert!(ok.validate().is_ok() && ok.enabled());
        assert!(
            !NovelViewConfig {
                mode: NovelMode::None,
                ..ok.clone()
            }
            .enabled()
        );
        let bad = [
            NovelViewConfig {
                depth_weight: f32::NAN,
                ..ok.clone()
            },
            NovelViewConfig {
                depth_weight: 2.0,
                ..ok.clone()
            },
            NovelViewConfig {
                after: Some(0),
                ..ok.clone()
            },
            NovelViewConfig {
                voxel: 0.0,
                ..ok.clone()
            },
            NovelViewConfig {
                scale: 0.0,
                ..ok.clone()
            },
            NovelViewConfig {
                scale: f64::NAN,
                ..ok.clone()
            },
            NovelViewConfig {
                offset: -1.0,
                ..ok.clone()
            },
            NovelViewConfig {
                extractor: Some(vec![]),
                ..ok.clone()
            },
            NovelViewConfig {
                max_color_error: Some(-0.1),
                ..ok.clone()
            },
            NovelViewConfig {
                max_color_error: Some(f64::NAN),
                ..ok.clone()
            },
            NovelViewConfig {
                color_weight: -0.5,
                ..ok.clone()
            },
        ];
        for (b, key) in bad.iter().zip([
            "depth_weight",
            "depth_weight",
            "after",
            "voxel",
            "scale",
            "scale",
            "offset",
            "extractor",
            "max_color_error",
            "max_color_error",
            "color_weight",
        ]) {
            let e = b.validate().expect_err("invalid");
            assert!(e.contains(key), "{e}");
        }
        // The check is off with null and stays off through the JSON.
        let off = NovelViewConfig {
            max_color_error: None,
            ..ok.clone()
        };
        assert!(off.validate().is_ok());
        let json = serde_json::to_string(&off).expect("json");
        assert!(json.contains("\"max_color_error\":null"), "{json}");
        let back: NovelViewConfig = serde_json::from_str(&json).expect("read back");
        assert_eq!(back, off);
    }

    #[test]
    fn a_configuration_written_before_the_loop_settings_reads_as_it_ran() {
        let old: NovelViewConfig =
            serde_json::from_str(r#"{"views": 24, "mode": "guided"}"#).expect("old configuration");
        assert_eq!(old.normalisation, Normalisation::MinmaxLogdet);
        assert_eq!(old.color_weight, 1.0);
        assert!(!old.mask_features);
        let new = NovelViewConfig {
            normalisation: Normalisation::RankQuantile { temperature: 0.25 },
            ..NovelViewConfig::default()
        };
        let json = serde_json::to_string(&new).expect("json");
        assert!(json.contains("\"normalisation\":\"rank:0.25\""), "{json}");
        assert_eq!(
            serde_json::from_str::<NovelViewConfig>(&json).expect("back"),
            new
        );
    }
}
