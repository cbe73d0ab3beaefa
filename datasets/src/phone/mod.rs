//! Phone captures with ARKit poses and LiDAR depth: the 3D Scanner App's
//! "All Data" export ([`scanner`]), Record3D's EXR + JPG and R3D exports
//! ([`record3d`]) and Polycam's raw data ([`polycam`]).
//!
//! Each format's reader lists its frames as a [`Capture`] (image, ARKit
//! camera-to-world pose, intrinsics at the image's size, depth and
//! confidence maps where the export has them, the mesh where it has one);
//! [`assemble`] turns any of them into a [`Scene`] the same way:
//!
//! - **Poses.** ARKit's cameras look down -z with y up (OpenGL axes); they
//!   are turned to OpenCV axes. ARKit's world is gravity-aligned with y up:
//!   it is rotated so that z is up and kept metric. Its horizontal axes
//!   point wherever the phone did when the capture began, so it is turned
//!   about z until the smallest rectangle around the footprint of the
//!   camera centres, the mesh and the depth maps (whichever it has) runs along
//!   x and y (a room's walls, so that the box is tight and the field no
//!   coarser than the room needs), and centred on their box. The
//!   map is the scene's [`WorldFrame`](crate::scene::WorldFrame) `arkit` (`scene.json`'s `world`), so
//!   `eval --frame capture` writes outputs in the export's own frame.
//! - **Depth.** The LiDAR map (about 256x192) sees what the colour camera
//!   sees at a lower resolution; it is carried into the colour camera at
//!   the training resolution by reprojection, as ScanNet's depth is
//!   ([`crate::scannet::reproject_depth`]), not stretched. Pixels below
//!   `min_depth_confidence` or beyond `max_depth` are no target. Where an
//!   export has no depth maps but a mesh, depth is ray-cast from the mesh.
//! - **Points.** The mesh's vertices, coloured from its texture, are the
//!   scene's point cloud; without a mesh, every `box_pixel_step`-th depth
//!   pixel of every frame, coloured by its image.
//! - **Box.** The scene box holds the cameras, the mesh and the depth maps,
//!   all of them: a mesh may cover less than the scan's depth maps.

mod assemble;
pub mod polycam;
pub mod record3d;
pub mod scanner;
pub mod source;

use std::path::{Path, PathBuf};

use model::geometry::Intrinsics;

use crate::error::DatasetError;
use crate::options::LoaderOptions;
use crate::scene::Scene;
pub use assemble::assemble;
pub use source::{ConfidenceSource, DepthSource, ImageSource};

/// Name of the capture frame phone scenes record (`--frame capture` or
/// `--frame arkit` in `eval`).
pub const ARKIT_FRAME: &str = "arkit";

/// One frame of a phone capture, as its export describes it.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureFrame {
    /// Name for output files and feature maps (e.g. `frame_00012`).
    pub name: String,
    /// The colour image.
    pub image: ImageSource,
    /// Camera-to-world, row-major, in ARKit's conventions: world y up
    /// (gravity-aligned), the camera looking down its -z with y up.
    pub pose: [[f64; 4]; 4],
    /// The file the pose was read from (named in errors).
    pub pose_file: PathBuf,
    /// Intrinsics of the colour camera at the size given in them (the
    /// image's own size, or the size the export states).
    pub intrinsics: Intrinsics,
    /// The LiDAR depth map, when the export has one for this frame.
    pub depth: Option<DepthSource>,
    /// Its confidence map, when the export has one.
    pub confidence: Option<ConfidenceSource>,
    /// The app's own sharpness score of the image, higher sharper, where
    /// it writes one (Polycam's `blur_score`).
    pub blur_score: Option<f64>,
}

/// A phone export's frames, mesh and what its reader left out.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Capture {
    /// Frames in capture order.
    pub frames: Vec<CaptureFrame>,
    /// The textured OBJ mesh, when the export has one.
    pub mesh: Option<PathBuf>,
    /// What the reader skipped or assumed, one line each.
    pub notes: Vec<String>,
}

impl Capture {
    /// Notes on the frames without a depth map (`place` names where the
    /// maps were looked for) and the depth maps without a confidence map.
    pub(crate) fn note_depth_coverage(&mut self, place: &str) {
        let n = self.frames.len();
        let with_depth = self.frames.iter().filter(|f| f.depth.is_some()).count();
        if with_depth == 0 {
            self.notes.push(format!("no depth maps in {place}"));
        } else if with_depth < n {
            self.notes.push(format!(
                "{} of {n} frames have no depth map",
                n - with_depth
            ));
        }
        let with_conf = self
            .frames
            .iter()
            .filter(|f| f.depth.is_some() && f.confidence.is_some())
            .count();
        if with_conf < with_depth {
            self.notes.push(format!(
                "{} depth maps have no confidence map: all their pixels are kept",
                with_depth - with_conf
            ));
        }
    }
}

/// The rotation from ARKit's world (y up) to the scene's (z up): x stays,
/// ARKit's y becomes z, and its z (towards the viewer at the session's
/// start) becomes -y.
pub const ARKIT_TO_Z_UP: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]];

/// The scene loaded from a phone capture, and what was left out or
/// assumed (one line each, printed by the callers).
pub struct Assembled {
    /// The scene.
    pub scene: Scene,
    /// Notes for the user.
    pub notes: Vec<String>,
    /// The training size chosen for the frames when none was asked for
    /// and it is not their own ([`crate::footprint::default_size`]), to be
    /// recorded in the scene's source.
    pub resolution: Option<(u32, u32)>,
}

/// Loads any phone format `loader` names from `dir`, with its feature maps,
/// printing its notes to stderr ([`crate::load_disk`]).
pub fn load_phone(dir: &Path, loader: &LoaderOptions) -> Result<Scene, DatasetError> {
    if !loader.format().is_phone() {
        return Err(not_phone(dir, loader));
    }
    crate::load_disk(dir, loader)
}

/// Reads the export of any phone format `loader` names from `dir` and
/// assembles it, without its feature maps.
pub(crate) fn assemble_export(
    dir: &Path,
    loader: &LoaderOptions,
) -> Result<Assembled, DatasetError> {
    let (read, options): (ReadCapture, _) = match loader {
        LoaderOptions::ScannerApp(o) => (scanner::read_capture, o),
        LoaderOptions::Record3d(o) => (record3d::read_capture, o),
        LoaderOptions::Polycam(o) => (polycam::read_capture, o),
        other => return Err(not_phone(dir, other)),
    };
    // Bad options are refused before the export is read.
    options.selection.check(dir)?;
    assemble(dir, options, read(dir)?, loader)
}

/// A phone format's reader of its export.
type ReadCapture = fn(&Path) -> Result<Capture, DatasetError>;

/// The error for a `loader` of another format than a phone's.
fn not_phone(dir: &Path, loader: &LoaderOptions) -> DatasetError {
    DatasetError::invalid(dir, format!("{} is not a phone format", loader.format()))
}
