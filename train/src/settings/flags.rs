//! The novel-view, occupancy-grid and head flags, each of which sets keys
//! of the configuration directly.

use crate::cli::Cli;
use crate::config::TrainConfig;

/// Lays the novel-view, occupancy-grid and head top-k flags over the
/// configuration (`--occupancy-grid` itself is a decided setting,
/// [`super::choices::Flags::of_cli`]).
pub fn apply_novel_and_grid(cli: &Cli, config: &mut TrainConfig) {
    if let Some(r) = cli.grid_resolution {
        config.occupancy.resolution = r;
    }
    let grid = &mut config.occupancy;
    let flags = [
        (cli.grid_early_samples, &mut grid.early_samples),
        (cli.grid_early_updates, &mut grid.early_updates),
        (cli.grid_dilation, &mut grid.dilation),
        (cli.grid_keep_dropped, &mut grid.keep_dropped_updates),
    ];
    for (flag, field) in flags {
        if let Some(v) = flag {
            *field = v;
        }
    }
    if let Some(k) = cli.head_top_k {
        config.model.head_top_k = (k > 0).then_some(k);
    }
    let novel = &mut config.novel;
    if let Some(n) = cli.novel_views {
        novel.views = n;
    }
    if let Some(a) = cli.novel_after {
        novel.after = Some(a);
    }
    if let Some(m) = cli.novel_views_mode {
        novel.mode = m;
    }
    if let Some(w) = cli.novel_depth_weight {
        novel.depth_weight = w;
    }
    if let Some(s) = cli.novel_scale {
        novel.scale = s;
    }
    if let Some(e) = cli.novel_max_color_error {
        novel.max_color_error = e.is_finite().then_some(e);
    }
    if let Some(o) = cli.novel_oracle {
        novel.oracle = Some(o);
    }
    if let Some(n) = cli.novel_normalisation {
        novel.normalisation = n;
    }
    if let Some(w) = cli.novel_color_weight {
        novel.color_weight = w;
    }
    if cli.novel_keep_fog {
        novel.mask_features = false;
    }
    if let Some(c) = &cli.extractor_command {
        // Refused before this point (`validate::cli`) when it cannot be split.
        novel.extractor = crate::validate::extractor_words(c).ok();
    }
}
