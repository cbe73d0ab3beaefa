//! Novel training views rendered by the field (OpenNeRF, Sec. 3.3): cameras
//! chosen by one of the ablation's modes (aimed at uncertain points,
//! interpolated along the capture path, or placed at random), rendered, run
//! through the scene's 2D feature extractor and compressed into the scene's
//! feature space, ready to be recorded and appended as training frames.
//!
//! [`cameras`] chooses the cameras ([`guided`] aims them at uncertain
//! points), [`extract`] renders them and reads their features, [`oracle`]
//! puts a synthetic scene's ground truth in place of either, and [`record`]
//! reads the views a run recorded back into its scene.

pub mod cameras;
pub mod config;
pub mod extract;
pub mod guided;
pub mod oracle;
pub mod record;
pub mod view;

pub use cameras::{AimedCamera, choose_cameras};
pub use config::{NovelMode, NovelViewConfig};
pub use extract::{check_extractor, render_views, scene_extractor};
pub use oracle::NovelOracle;
pub use view::ExtractedView;
