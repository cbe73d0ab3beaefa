//! The novel views a run recorded in its `novel/` directory: written once
//! when they are made, read back into the scene by every later command
//! (a resumed training run, `eval`), so that all of them see the same bytes.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use clap::ValueEnum;
use datasets::Scene;
use datasets::novel_record::NovelView;

use super::config::NovelMode;
use super::oracle::NovelOracle;
use crate::error::OpsError;

/// How the recorded cameras were chosen, and whether a ground truth stood
/// in for the field's render (so that such views are never mistaken for
/// the method's). Written in the record as `guided` or
/// `guided (ground-truth labels)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ViewChoice {
    /// The camera mode.
    pub mode: NovelMode,
    /// The ground truth used in place of the render, if any.
    pub oracle: Option<NovelOracle>,
}

impl fmt::Display for ViewChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.oracle {
            Some(o) => write!(f, "{} (ground-truth {})", self.mode.name(), o.name()),
            None => f.write_str(self.mode.name()),
        }
    }
}

impl FromStr for ViewChoice {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let (mode, oracle) = match s.split_once(" (ground-truth ") {
            Some((mode, rest)) => {
                let name = rest
                    .strip_suffix(')')
                    .ok_or_else(|| format!("unknown novel-view mode {s:?}"))?;
                let oracle = NovelOracle::value_variants()
                    .iter()
                    .copied()
                    .find(|o| o.name() == name)
                    .ok_or_else(|| format!("unknown ground truth {name:?} in {s:?}"))?;
                (mode, Some(oracle))
            }
            None => (s, None),
        };
        let mode = NovelMode::value_variants()
            .iter()
            .copied()
            .find(|m| m.name() == mode)
            .ok_or_else(|| format!("unknown novel-view mode {mode:?}"))?;
        Ok(Self { mode, oracle })
    }
}

/// Novel views recorded by a run: the iteration they join training at,
/// their frame indices in the rebuilt scene and how they were chosen.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordedViews {
    /// First iteration whose batch may draw them.
    pub at: usize,
    /// Their indices in the scene.
    pub frames: Vec<usize>,
    /// How their cameras were chosen.
    pub choice: ViewChoice,
}

/// Appends the views recorded in `dir` (a run's `novel/`), if any, to
/// `scene`.
pub fn append_recorded(scene: &mut Scene, dir: &Path) -> Result<Option<RecordedViews>, OpsError> {
    let Some((record, frames)) = datasets::novel_record::append_recorded(scene, dir)? else {
        return Ok(None);
    };
    let index = dir.join(datasets::novel_record::INDEX);
    let choice = record
        .mode
        .parse()
        .map_err(|m: String| OpsError::json(&index, m))?;
    Ok(Some(RecordedViews {
        at: record.added_at,
        frames,
        choice,
    }))
}

/// Records `views` in `dir` (a run's `novel/`) as made at `iteration`.
pub fn write_record(
    dir: &Path,
    choice: ViewChoice,
    iteration: usize,
    views: &[NovelView],
) -> Result<(), OpsError> {
    datasets::novel_record::write_record(dir, &choice.to_string(), iteration, views)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_choices_read_back_as_written() {
        for mode in [NovelMode::Trajectory, NovelMode::Random, NovelMode::Guided] {
            for oracle in [None, Some(NovelOracle::Renders), Some(NovelOracle::Labels)] {
                let c = ViewChoice { mode, oracle };
                assert_eq!(c.to_string().parse::<ViewChoice>(), Ok(c));
            }
        }
        let labels = "guided (ground-truth labels)".parse::<ViewChoice>();
        assert_eq!(
            labels,
            Ok(ViewChoice {
                mode: NovelMode::Guided,
                oracle: Some(NovelOracle::Labels)
            })
        );
        for bad in [
            "sideways",
            "guided (ground-truth dreams)",
            "guided (ground-truth labels",
        ] {
            assert!(bad.parse::<ViewChoice>().is_err(), "{bad}");
        }
    }
}
