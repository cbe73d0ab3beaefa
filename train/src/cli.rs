//! The command line of the `train` binary.

use std::path::PathBuf;

use clap::Parser;

use field_ops::backend::BackendArgs;

/// Which kind of scene to train on (`--dataset`).
pub use field_ops::dataset_arg::DatasetArg as DatasetKind;

impl Cli {
    /// The scene source asked for: `--dataset`, else `auto` when `--data`
    /// is given, else the synthetic scene.
    pub fn dataset_kind(&self) -> DatasetKind {
        match (self.dataset, &self.data) {
            (Some(kind), _) => kind,
            (None, Some(_)) => DatasetKind::Auto,
            (None, None) => DatasetKind::Synthetic,
        }
    }
}

pub use datasets::options::{DepthConfidence, Resolution};
pub use datasets::synthetic::SceneSize;

/// Train an OpenNeRF field (colour, depth and an open-set feature head) on a
/// posed capture or on the built-in synthetic room.
///
/// Without arguments it trains a small model on the synthetic CI scene for a
/// few minutes on the CPU and prints where the results are.
// A flag given twice takes its last value, so that a scene list's entry
// (`batch`) can override the flags its defaults give.
#[derive(Debug, Clone, Parser)]
#[command(name = "train", version, args_override_self = true)]
pub struct Cli {
    /// Compute backend and device.
    #[command(flatten)]
    pub compute: BackendArgs,

    /// Scene source [default: auto when --data is given, else synthetic].
    #[arg(long, value_enum)]
    pub dataset: Option<DatasetKind>,
    /// Scene directory (any format but synthetic), or a Record3D `.r3d` file.
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Synthetic scene: generator seed.
    #[arg(long, default_value_t = 0)]
    pub scene_seed: u64,
    /// Synthetic scene: size preset.
    #[arg(long, value_enum, default_value_t = SceneSize::Ci)]
    pub scene_size: SceneSize,
    /// Feature maps (`.npy` directory or stacked file) for a Replica, COLMAP
    /// or phone scene: one `H x W x D` map per frame kept, named after the
    /// frame (Replica `frameNNNNNN.npy`, COLMAP the image stem, phone
    /// captures `frame_NNNNN.npy`) [default: none].
    #[arg(long)]
    pub features: Option<PathBuf>,
    /// Make the feature maps in process with this CLIP model directory
    /// (both towers, one checkpoint: Hugging Face `CLIPModel` files or
    /// OpenCLIP's `open_clip_model.safetensors` + `open_clip_config.json`,
    /// with the tokenizer files): dense patch features of every frame, for any
    /// scene (on disk, or the synthetic one instead of its simulated
    /// extractor). The maps are written once, as f16 `.npy`, to
    /// --features-out (default `<out>/features`) and reused when they exist
    /// for the same model, variant and size; the text tower embeds the
    /// classes here and the queries in `eval`; novel views are extracted
    /// with it too.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["features", "extractor_command"])]
    pub vlm: Option<PathBuf>,
    /// --vlm's training-free dense variant of the last block: `naclip`
    /// (key-key attention plus a Gaussian window over the patches),
    /// `clearclip` (query-query attention) or `maskclip` (values only)
    /// [default: naclip].
    #[arg(long, requires = "vlm", value_parser = field_ops::vlm_maps::dense_variant_parser())]
    pub dense: Option<clip::DenseVariant>,
    /// --vlm resizes each image's short side to this many pixels (at least
    /// the model's input size) before sliding windows of the input size over
    /// it every half window; the maps have one cell per patch, so larger is
    /// finer and slower (time grows with its square) [default: 336, or the
    /// model's input size if larger].
    // Named as in `eval extract`; `--vlm-short-side`, its former name, is a
    // hidden alias so that older scripts still run.
    #[arg(long, alias = "vlm-short-side", requires = "vlm")]
    pub short_side: Option<usize>,
    /// Where --vlm writes (or finds) its maps [default: <out>/features].
    #[arg(long, value_name = "DIR", requires = "vlm")]
    pub features_out: Option<PathBuf>,
    /// Compression of the feature maps: `auto` keeps the principal
    /// components explaining 99% of their variance, `K` keeps K components,
    /// `off` trains on the full dimension D. The basis is fitted on a sample
    /// streamed from the maps (never all of them at full D in memory), stored
    /// in the run's `scene.json` and reused whenever the scene is rebuilt
    /// [default: auto for maps on disk; the synthetic scene's size preset:
    /// off for ci, auto for bench].
    #[arg(long, value_name = "auto|off|K")]
    pub pca: Option<datasets::features::PcaSetting>,
    /// Scenes on disk: keep every Nth frame (N >= 1), in the format's
    /// order (capture order; image name order for COLMAP and LLFF; the
    /// transforms file's order for Blender), before --max-frames
    /// [default: 1, every frame; a Record3D video: about 3 frames a
    /// second of its `fps`].
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = datasets::options::parse_count)]
    pub stride: Option<usize>,
    /// Scenes on disk: keep the sharpest frame (highest variance of the
    /// Laplacian of its luminance; Polycam's own blur score where every
    /// frame has one) of each run of K consecutive frames, instead of
    /// every Nth (--stride). Every image is decoded once more to score it.
    #[arg(long, value_name = "K", allow_negative_numbers = true, conflicts_with = "stride",
          value_parser = datasets::options::parse_count)]
    pub sharpest_of: Option<usize>,
    /// Scenes on disk: the most memory the loaded frames may take (e.g.
    /// 8G, 512M); a capture that would need more is refused before its
    /// images are decoded, naming the flags that make it fit [default: 80%
    /// of the memory the machine has available].
    #[arg(long, value_name = "SIZE", value_parser = datasets::footprint::parse_memory)]
    pub max_memory: Option<u64>,
    /// Scenes on disk: keep at most N frames (N >= 1), the first N after
    /// --stride [default: all].
    #[arg(long, value_name = "N", allow_negative_numbers = true,
          value_parser = datasets::options::parse_count)]
    pub max_frames: Option<usize>,
    /// Scenes on disk: resample the images to WxH, intrinsics scaled
    /// (Replica, ScanNet, phone captures; Blender, LLFF and COLMAP read
    /// pre-sized images: use --downscale) [default: the images' own size;
    /// phone captures: a long side over 1280 px is trained at 960, and
    /// smaller still where the frames would take over 2 GiB].
    #[arg(long, conflicts_with = "downscale")]
    pub resolution: Option<Resolution>,
    /// Blender, LLFF and COLMAP: divide the image size by N (Blender
    /// resamples its images, LLFF and COLMAP read the downscaled copies
    /// `images_N/`); the other formats take --resolution [default: the
    /// loader's: full size; LLFF `images_8/` or its most downscaled copy].
    #[arg(long)]
    pub downscale: Option<u32>,
    /// Phone captures: LiDAR depth pixels less sure than this are no depth
    /// target (ARKit's confidence levels) [default: high].
    #[arg(long, value_enum)]
    pub min_depth_confidence: Option<DepthConfidence>,
    /// Phone captures: depth beyond this many metres is no target (the
    /// LiDAR's range) [default: 5].
    #[arg(long, value_name = "METRES")]
    pub max_depth: Option<f64>,
    /// COLMAP: use the dense depth maps (`stereo/depth_maps/*.geometric.bin`)
    /// as depth targets; zero and NaN depths are no target.
    #[arg(long)]
    pub colmap_depth: bool,
    /// COLMAP: the sparse points as depth targets, each point's z-depth at
    /// the pixels of the features that observe it (as DS-NeRF supervises
    /// few views); a quarter of each batch (`sampler.depth_rays`, 64 of
    /// the default 256 rays) is drawn from those pixels.
    /// `auto` (the default): off, measured on real captures
    /// (docs/measurements/real-capture-defaults.md); `on` where the model
    /// has no sparse points or with --colmap-depth is an error. `train`
    /// prints its choice.
    #[arg(long, value_enum)]
    pub sparse_depth: Option<crate::settings::args::SparseDepthArg>,
    /// Scenes on disk: grow the scene box by this fraction of its largest
    /// side on every side (0.5: a box twice as large). The field models
    /// only what lies in the box; what lies past it is painted on its
    /// walls [default: 0.05].
    #[arg(long, value_name = "FRACTION", allow_negative_numbers = true)]
    pub box_margin: Option<f64>,
    /// Hold out every Nth frame (frames 0, N, 2N, ...) for evaluation (N >= 2).
    #[arg(long, default_value_t = 8)]
    pub holdout_every: usize,

    /// Speed/accuracy preset from the measured sweeps (README): `fast` (16
    /// samples per ray and level, occupancy grid, 1600 iterations),
    /// `balanced` (24 samples, grid, 2300) or `best` (24 samples, grid,
    /// 5000), each with 256 rays a batch for an object seen from outside;
    /// where most cameras stand inside the scene box (a room), 128 rays a
    /// batch and 2600, 4150 or 9000 iterations. A `--config` file and the
    /// flags below apply on top of it [default: none, the built-in
    /// configuration].
    #[arg(long, value_enum)]
    pub preset: Option<crate::preset::Preset>,
    /// Full training configuration (JSON: model, sampler, losses, optimiser,
    /// schedule, logging) [default: built-in, sized for a 2-core CPU].
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Override: total training iterations (the schedule's length).
    #[arg(long)]
    pub iters: Option<usize>,
    /// Override: rays per batch [default: 256, on every kind of capture;
    /// a `--preset` on a room: 128 (docs/reference/capture-defaults.md)].
    #[arg(long)]
    pub rays: Option<usize>,
    /// Override: samples per ray and level [default: 48; a forward-facing
    /// capture: 16; the fast field with its proposal networks on a
    /// photographed object: 24].
    #[arg(long)]
    pub samples: Option<usize>,
    /// Override: width of the MLP trunk.
    #[arg(long)]
    pub width: Option<usize>,
    /// Override: number of trunk layers.
    #[arg(long)]
    pub depth: Option<usize>,
    /// Override: weight of the open-set feature loss.
    #[arg(long, allow_negative_numbers = true)]
    pub lambda_open: Option<f32>,
    /// Override: weight of the depth loss (0 disables it).
    #[arg(long, allow_negative_numbers = true)]
    pub lambda_depth: Option<f32>,
    /// Override: initial learning rate (the final rate keeps its ratio to it).
    #[arg(long, allow_negative_numbers = true)]
    pub lr: Option<f64>,
    /// Weight of a few-view prior: every step also renders small patches
    /// seen from viewpoints between neighbouring training cameras, where no
    /// photograph constrains the field, and asks their depth to be smooth
    /// (RegNeRF's geometry regulariser; `losses.unseen_patches`,
    /// `unseen_patch_side` and `unseen_patch_stride` in `--config` set the
    /// patches). 0 (the default) renders none; docs/measurements/unbounded.md measures it.
    #[arg(long, value_name = "WEIGHT", allow_negative_numbers = true)]
    pub unseen_depth: Option<f32>,
    /// Override: evaluate the feature head only on the K samples of largest
    /// weight per ray (0: on every sample, the default configuration's choice).
    #[arg(long)]
    pub head_top_k: Option<usize>,
    /// Override: seed of the initialisation, the ray sampler and the jitter.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Override: a `metrics.jsonl` line every N iterations. The steps in
    /// between read nothing back from the device: their losses are read
    /// together when the line is written (and before an evaluation or a
    /// checkpoint) [default: 25, or the `--config` file's
    /// `logging.log_every`].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub log_every: Option<u64>,

    /// Stop cleanly after this many seconds of training, then evaluate and
    /// save. Without `--iters`, the schedule's length is fitted to the
    /// budget from the time of the first steps (recorded in `config.json`),
    /// so the learning rate decays over the whole budget.
    #[arg(long, allow_negative_numbers = true)]
    pub time_budget: Option<f64>,
    /// Stop cleanly after this iteration although the schedule is longer
    /// (e.g. to be resumed later with the same schedule).
    #[arg(long)]
    pub stop_at: Option<usize>,
    /// Novel views (paper Sec. 3.3): render this many views with the field part-way
    /// through training, run the scene's 2D feature extractor on them and
    /// add them as training frames (0: none). Counted in the iteration and
    /// time budget.
    #[arg(long)]
    pub novel_views: Option<usize>,
    /// Iteration the novel views are added at [default: half the schedule].
    #[arg(long)]
    pub novel_after: Option<usize>,
    /// How novel cameras are chosen: `guided` aims them at the points whose
    /// training features disagree most, `trajectory` interpolates between
    /// consecutive training cameras, `random` places them uniformly in the
    /// scene box, `none` adds nothing (the ablation's baseline).
    #[arg(long, value_enum)]
    pub novel_views_mode: Option<field_ops::novel::NovelMode>,
    /// Weight of the novel views' rendered depth in the depth loss, in
    /// [0, 1] (sensor depth weighs 1) [default: 0.1].
    #[arg(long, allow_negative_numbers = true)]
    pub novel_depth_weight: Option<f32>,
    /// Novel views are rendered at this fraction of the capture resolution,
    /// in (0, 1]; rendering time goes with its square [default: 0.5].
    #[arg(long, allow_negative_numbers = true)]
    pub novel_scale: Option<f64>,
    /// Guided views are kept only where the field renders their target
    /// within this colour difference (RMS, colours in [0, 1]) of what the
    /// capture saw there: elsewhere the field has not learnt the surface and
    /// the extractor would label its wrong render [default: inf, no check].
    #[arg(long, allow_negative_numbers = true)]
    pub novel_max_color_error: Option<f64>,
    /// Diagnostic for synthetic scenes: take the novel views from the
    /// scene's ground truth instead of the pipeline, to measure what camera
    /// choice could give. `renders`: colour and depth ray-traced from the
    /// scene (a perfect field), read by the scene's extractor; `labels`:
    /// also features that name every pixel's true class (a perfect
    /// extractor). [default: neither, the method as specified]
    #[arg(long, value_enum)]
    pub novel_oracle: Option<field_ops::novel::oracle::NovelOracle>,
    /// How a point's uncertainty (the log-determinant of its feature
    /// covariance) becomes its chance to be a guided target:
    /// `minmax-logdet` rescales the log-determinant to [0, 1];
    /// `det-over-max` is the generalized variance over its largest value
    /// (the paper's draw); `rank:T` is the point's rank quantile to the power
    /// 1/T, which makes about T/(1+T) of the points candidates (e.g.
    /// `rank:0.25`) [default: minmax-logdet]
    #[arg(long)]
    pub novel_normalisation: Option<field_ops::uncertainty::Normalisation>,
    /// Weight of the novel views' rendered colour in the colour loss, in
    /// [0, 1] (captured colour weighs 1): the field's own render teaches it
    /// nothing new, 0 keeps it from reinforcing its errors [default: 1]
    #[arg(long, allow_negative_numbers = true)]
    pub novel_color_weight: Option<f32>,
    /// Keep the feature targets of novel-view map cells whose render is
    /// mostly transparent (opacity below 0.5): by default such cells carry
    /// no feature target, since the extractor reads them off fog
    #[arg(long)]
    pub novel_keep_fog: bool,
    /// For scenes on disk: the 2D feature extractor run on the rendered
    /// views, as `PROGRAM [ARGS...]`, split into words as a shell would
    /// (quote a path with spaces: `'/my models/extract' --fast`); it is called as
    /// `PROGRAM ARGS... IN_DIR OUT_DIR`, reads `IN_DIR/<name>.png` and must
    /// write `OUT_DIR/<name>.npy` (H x W x D). Synthetic scenes use their own.
    #[arg(long)]
    pub extractor_command: Option<String>,
    /// Empty-space skipping: keep an occupancy grid of the field's density
    /// over the scene box (a complete grid for the first 256 iterations,
    /// then refreshed every 16 with decay, conservatively: see the
    /// `--grid-*` flags) and sample each ray only between its first and
    /// last occupied cell; rays that cross no occupied cell are not
    /// rendered (they see the background) once the warm-up of
    /// `--grid-keep-dropped` refreshes is over. The grid is saved with
    /// the checkpoints and as `occupancy.bin`, and `eval` renders with it.
    #[arg(long)]
    pub occupancy_grid: bool,
    /// What gives density and colour: `mip` (the paper's Mip-NeRF MLP, 8 x
    /// 256 at its size, on the IPE of each sample's frustum), `fast`
    /// (nerfacto's: a multiresolution hash grid, a density MLP of 64 and a
    /// colour MLP of 2 x 64 on a spherical-harmonics view encoding; about a
    /// hundredth of the work a sample; `model.fast` in a `--config` file
    /// sizes it) or `auto` (`mip` on every kind of capture until the fast
    /// field is measured better there: docs/measurements/fast-field.md).
    /// `--width` and `--depth` size the Mip-NeRF MLP only. `train` prints its
    /// choice and why.
    #[arg(long, value_enum, default_value_t = crate::settings::args::FieldModelArg::Auto)]
    pub field_model: crate::settings::args::FieldModelArg,
    /// The field's extent: `box` (the scene box mapped to [-pi, pi]^3),
    /// `unbounded` (Mip-NeRF 360's contraction: the ball around the scene
    /// box kept, everything beyond contracted, rays from where they enter
    /// the scene box to effectively infinite distance; no occupancy grid)
    /// or `auto` (unbounded for a photographed object walked around and
    /// for an open scene, where it was measured better, box otherwise:
    /// docs/reference/capture-defaults.md). `train` prints its choice and
    /// why.
    #[arg(long, value_enum, default_value_t = crate::settings::args::FieldArg::Auto)]
    pub field: crate::settings::args::FieldArg,
    /// Where the field samples: `coarse-fine` (Mip-NeRF's two levels of the
    /// one field, `--samples` each), `proposal` (proposal rounds trained by
    /// the interlevel loss, then `--samples` of the field: for the Mip-NeRF
    /// field Mip-NeRF 360's two rounds of 64 samples of a small density MLP,
    /// for the fast field two rounds of a small hash-grid density network,
    /// of 32 and 16 samples, or 64 and 32 on a room or an open scene) or
    /// `auto` (coarse-fine for the Mip-NeRF field, measured more accurate
    /// and faster at the default sizes: docs/measurements/unbounded.md;
    /// proposal for the fast field, measured better than its coarse and fine
    /// levels on lego and the bench room in equal seconds:
    /// docs/measurements/fast-field.md).
    #[arg(long, value_enum, default_value_t = crate::settings::args::SamplerArg::Auto)]
    pub sampler: crate::settings::args::SamplerArg,
    /// The photographs' appearance: `exposure` learns a gain and an offset
    /// per colour channel for each training photograph (captures whose
    /// photographs differ in exposure or white balance), applied to its
    /// rays' colours in the training loss only, so that the field renders
    /// the photographs' common exposure; `embedding` learns a code per
    /// training photograph that the colour branch takes beside the view
    /// direction (nerfacto's appearance embedding, `model.appearance.dim`
    /// numbers, 16 by default), and renders every other view with the zero
    /// code; `none` takes every photograph as taken at one exposure; `auto`
    /// is `embedding` for a photographed object walked around (measured to
    /// lift its held-out views: docs/measurements/unbounded.md), else
    /// `none`, unless the `--config` file sets `model.exposure` or
    /// `model.appearance`. `train` prints its choice.
    #[arg(long, value_enum, default_value_t = crate::settings::args::AppearanceArg::Auto)]
    pub appearance: crate::settings::args::AppearanceArg,
    /// Refine the training photographs' camera poses with the field: `on`
    /// learns a small rotation about each camera's centre and a shift of
    /// that centre per training photograph (nerfstudio's camera optimiser,
    /// BARF), applied to its rays in training only, at
    /// `optimiser.pose_lr_scale` times the field's rate and held near zero
    /// by `losses.pose_penalty`; held-out and novel views keep their poses.
    /// `off` uses the poses as given; `auto` (the default) is `off` unless
    /// the `--config` file sets `model.pose` (docs/measurements/unbounded.md). `train`
    /// prints its choice.
    #[arg(long, value_enum)]
    pub pose_refine: Option<crate::settings::args::PoseRefineArg>,
    /// Give the field's MLP a multiresolution hash encoding of each
    /// sample beside its IPE (Instant-NGP's, as nerfacto uses it: 16
    /// levels from 16 to 512 cells across the field's domain, 2^15 rows of
    /// 2 learned features each; `model.hash` in a `--config` file sets
    /// others): fine detail is learned in far fewer iterations, at about
    /// twice the seconds per iteration on the CPU. `auto` (the default) is
    /// `on` for a photographed object walked around, where it was
    /// measured to lift the held-out views at equal seconds
    /// (docs/measurements/unbounded.md), else `off` unless the `--config`
    /// file sets `model.hash`.
    /// `train` prints its choice.
    #[arg(long, value_enum)]
    pub hash_grid: Option<crate::settings::args::HashGridArg>,
    /// Cells per axis of the occupancy grid, in 2..=256; a refresh costs one
    /// density query per cell [default: 32].
    #[arg(long)]
    pub grid_resolution: Option<usize>,
    /// Jittered density samples per grid cell at each early refresh (the
    /// cell keeps their maximum, so thin structures are not freed on one
    /// unlucky sample), in 1..=32 [default: 8].
    #[arg(long)]
    pub grid_early_samples: Option<usize>,
    /// Early refreshes of the occupancy grid: they take
    /// `--grid-early-samples` points per cell and keep the maximum over all
    /// of them, and every cell stays occupied until they are done
    /// [default: 4].
    #[arg(long)]
    pub grid_early_updates: Option<usize>,
    /// Cells around each occupied grid cell that count as occupied too, in
    /// 0..=4 (1: its 26 neighbours; 0: none) [default: 0].
    #[arg(long)]
    pub grid_dilation: Option<usize>,
    /// Grid refreshes during which training still renders the rays that
    /// cross no occupied cell, over their whole length, so that a region
    /// freed by mistake keeps a loss (0: skip them at once) [default: 8].
    #[arg(long)]
    pub grid_keep_dropped: Option<usize>,
    /// Run directory [default: runs/<dataset>-<unix time>].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Continue the run in DIR from its newest checkpoint (same configuration,
    /// schedule and sampler stream; `--iters`, `--time-budget` and `--stop-at`
    /// may be given, other options are taken from the run).
    #[arg(long, conflicts_with_all = ["config", "out", "data"])]
    pub resume: Option<PathBuf>,
    /// Skip the final full-resolution render of the held-out views (their
    /// PNGs and the whole-view figures); the summary then holds the figures
    /// of the interior pixel sample the periodic evaluations use. Saves
    /// minutes on large scenes.
    #[arg(long)]
    pub no_final_render: bool,
    /// No progress bar (log lines only).
    #[arg(long)]
    pub quiet: bool,
    /// Serve the run's web viewer while training (the page of `eval view`:
    /// the points by class, text queries, renders), refreshed from the
    /// current field every --viewer-every seconds. It stops with the
    /// training.
    #[arg(long)]
    pub viewer: bool,
    /// Port of --viewer (0: any free port).
    #[arg(long, default_value_t = 7007, requires = "viewer")]
    pub viewer_port: u16,
    /// Address --viewer listens on: 127.0.0.1 keeps it on this machine (the
    /// printed `ssh -L` line reaches it); 0.0.0.0 opens it to every interface.
    #[arg(long, default_value = "127.0.0.1", requires = "viewer")]
    pub viewer_host: String,
    /// Seconds between refreshes of --viewer's field (each refresh costs
    /// the page's points one field query when the page asks for them).
    #[arg(long, default_value_t = 10.0, requires = "viewer")]
    pub viewer_every: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn resolution_parses_and_rejects() {
        let r: Resolution = "320x180".parse().unwrap();
        assert_eq!((r.width, r.height), (320, 180));
        assert!("320".parse::<Resolution>().is_err());
        assert!("0x10".parse::<Resolution>().is_err());
        assert!("ax10".parse::<Resolution>().is_err());
    }

    #[test]
    fn cli_is_consistent_and_defaults_to_synthetic_flex() {
        Cli::command().debug_assert();
        let cli = Cli::try_parse_from(["train"]).unwrap();
        assert_eq!(cli.compute, BackendArgs::default());
        assert_eq!(cli.dataset_kind(), DatasetKind::Synthetic);
        assert!(cli.resume.is_none());
        let cli = Cli::try_parse_from([
            "train",
            "--dataset",
            "blender",
            "--data",
            "/d",
            "--downscale",
            "8",
            "--iters",
            "100",
            "--backend",
            "ndarray",
        ])
        .unwrap();
        assert_eq!(cli.downscale, Some(8));
        assert_eq!(cli.iters, Some(100));
        assert_eq!(cli.compute.backend, crate::BackendKind::Ndarray);
        assert!(Cli::try_parse_from(["train", "--resolution", "1x1", "--downscale", "2"]).is_err());
    }

    #[test]
    fn short_side_keeps_its_former_name_as_an_alias() {
        for flag in ["--short-side", "--vlm-short-side"] {
            let cli = Cli::try_parse_from(["train", "--vlm", "/m", flag, "448"]).unwrap();
            assert_eq!(cli.short_side, Some(448), "{flag}");
        }
    }

    #[test]
    fn paper_scene_sizes_are_accepted() {
        for size in ["paper", "paper-full"] {
            let cli = Cli::try_parse_from(["train", "--scene-size", size]).unwrap();
            match crate::data::source_from_cli(&cli).unwrap() {
                datasets::SceneSource::Synthetic { size: s, .. } => assert_eq!(s, size),
                other => panic!("--scene-size {size} gave {other:?}"),
            }
        }
        assert!(Cli::try_parse_from(["train", "--scene-size", "paper_full"]).is_err());
    }
}
