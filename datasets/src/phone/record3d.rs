//! Record3D's exports, the "EXR + JPG sequence" and the app's own `.r3d`
//! file (a ZIP archive, read as it is or unzipped into a directory):
//!
//! ```text
//! EXR + JPG                      R3D (scan.r3d, or a directory of its contents)
//! <dir>/metadata.json            metadata         w, h (colour size), K (3x3, column-major),
//!                                                 poses ([qx, qy, qz, qw, tx, ty, tz] per frame),
//!                                                 dw, dh (depth size, where stated)
//! <dir>/rgb/<i>.jpg              rgbd/<i>.jpg     the colour image of frame <i>
//! <dir>/depth/<i>.exr            rgbd/<i>.depth   LiDAR depth, metres: a float EXR | LZFSE-compressed
//!                                                 float32 little-endian, dw x dh (256x192)
//! <dir>/conf/<i>.png             rgbd/<i>.conf    its confidence, levels 0, 1, 2: an 8-bit PNG |
//!                                                 LZFSE-compressed u8, dw x dh
//! ```
//!
//! Frames are the images, in the order of `<i>`; frame `<i>`'s pose is
//! `poses[<i>]`: a unit quaternion (scalar last) and the camera centre, the
//! camera-to-world in ARKit's conventions. The intrinsics `K` are at the
//! colour size `w` x `h`. Without `dw`/`dh`, an EXR's size is its own and a
//! `.depth` map's is inferred from its length (256x192 or 640x480). Depth
//! and confidence maps are optional per frame. `fps` sets the default
//! stride ([`default_stride`]). Not read: `initPose`,
//! any other key of the metadata, and the archive's other entries (`icon`,
//! sound); nothing is extracted to disk.

mod metadata;
#[cfg(test)]
mod tests;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

pub use metadata::{Metadata, intrinsics_column_major, quaternion_pose};

use super::source::decode::{entry_path, read_zip_entry, zip_names};
use super::source::{ByteSource, ConfidenceSource, DepthSource, ImageSource, ZipEntry};
use super::{Capture, CaptureFrame};
use crate::error::DatasetError;

/// Where an export's files are.
enum Store {
    /// A directory.
    Dir(PathBuf),
    /// A ZIP archive and the names of its entries.
    Zip {
        archive: PathBuf,
        names: BTreeSet<String>,
    },
}

impl Store {
    /// The name errors give the file `name` (`/`-separated, relative).
    fn describe(&self, name: &str) -> PathBuf {
        match self {
            Self::Dir(d) => d.join(name),
            Self::Zip { archive, .. } => entry_path(archive, name),
        }
    }

    fn exists(&self, name: &str) -> bool {
        match self {
            Self::Dir(d) => d.join(name).is_file(),
            Self::Zip { names, .. } => names.contains(name),
        }
    }

    fn read(&self, name: &str) -> Result<Vec<u8>, DatasetError> {
        match self {
            Self::Dir(d) => {
                std::fs::read(d.join(name)).map_err(|e| DatasetError::io(d.join(name), e))
            }
            Self::Zip { archive, .. } => read_zip_entry(archive, name),
        }
    }

    fn bytes(&self, name: &str) -> ByteSource {
        match self {
            Self::Dir(d) => ByteSource::File(d.join(name)),
            Self::Zip { archive, .. } => ByteSource::Zip(ZipEntry {
                archive: archive.clone(),
                name: name.to_owned(),
            }),
        }
    }

    fn image(&self, name: &str) -> ImageSource {
        match self.bytes(name) {
            ByteSource::File(p) => ImageSource::File(p),
            ByteSource::Zip(z) => ImageSource::Zip(z),
        }
    }

    /// The files `<folder>/<i>.<ext>` (ext lower-cased, one of `exts`) by
    /// `i`, as names relative to the store.
    fn numbered(&self, folder: &str, exts: &[&str]) -> Result<BTreeMap<u64, String>, DatasetError> {
        let files: Vec<String> = match self {
            Self::Dir(d) => {
                let dir = d.join(folder);
                let mut files = Vec::new();
                for e in std::fs::read_dir(&dir).map_err(|e| DatasetError::io(&dir, e))? {
                    let p = e.map_err(|e| DatasetError::io(&dir, e))?.path();
                    if let Some(name) = p.file_name().and_then(|n| n.to_str())
                        && p.is_file()
                    {
                        files.push(name.to_owned());
                    }
                }
                files
            }
            Self::Zip { names, .. } => names
                .iter()
                .filter_map(|n| n.strip_prefix(folder)?.strip_prefix('/'))
                .filter(|n| !n.contains('/'))
                .map(str::to_owned)
                .collect(),
        };
        let mut found = BTreeMap::new();
        for file in files {
            let Some((stem, ext)) = file.rsplit_once('.') else {
                continue;
            };
            if exts.contains(&ext.to_lowercase().as_str())
                && let Ok(i) = stem.parse::<u64>()
            {
                let name = format!("{folder}/{file}");
                if let Some(other) = found.insert(i, name.clone()) {
                    return Err(DatasetError::invalid(
                        self.describe(&name),
                        format!("frame {i} has two files ({other})"),
                    ));
                }
            }
        }
        Ok(found)
    }
}

/// The two exports' file names.
struct Layout {
    /// The R3D layout (LZFSE maps), else EXR + JPG (EXR and PNG maps).
    r3d: bool,
    metadata: &'static str,
    images: &'static str,
    image_exts: &'static [&'static str],
    depth: fn(u64) -> String,
    confidence: fn(u64) -> String,
}

const EXR_JPG: Layout = Layout {
    r3d: false,
    metadata: "metadata.json",
    images: "rgb",
    image_exts: &["jpg", "jpeg", "png"],
    depth: |i| format!("depth/{i}.exr"),
    confidence: |i| format!("conf/{i}.png"),
};

const R3D: Layout = Layout {
    r3d: true,
    metadata: "metadata",
    images: "rgbd",
    image_exts: &["jpg", "jpeg"],
    depth: |i| format!("rgbd/{i}.depth"),
    confidence: |i| format!("rgbd/{i}.conf"),
};

/// The store and layout of the export at `path`.
fn open(path: &Path) -> Result<(Store, &'static Layout), DatasetError> {
    let meta = std::fs::metadata(path).map_err(|e| DatasetError::io(path, e))?;
    if meta.is_file() {
        let names = zip_names(path)?.into_iter().collect();
        return Ok((
            Store::Zip {
                archive: path.to_path_buf(),
                names,
            },
            &R3D,
        ));
    }
    if path.join("rgbd").is_dir() {
        return Ok((Store::Dir(path.to_path_buf()), &R3D));
    }
    if path.join("rgb").is_dir() {
        return Ok((Store::Dir(path.to_path_buf()), &EXR_JPG));
    }
    let r3d: Vec<String> = std::fs::read_dir(path)
        .map_err(|e| DatasetError::io(path, e))?
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.to_lowercase().ends_with(".r3d"))
        .collect();
    let hint = match r3d.first() {
        Some(f) => format!(" (it holds {f}: pass that file itself)"),
        None => String::new(),
    };
    Err(DatasetError::invalid(
        path,
        format!(
            "not a Record3D export: no rgb/ (EXR + JPG export) nor rgbd/ (an unzipped .r3d){hint}"
        ),
    ))
}

/// Frames a second of a Record3D video kept by default: neighbouring
/// frames of a 60 fps video nearly repeat each other, and a capture of
/// hundreds of them costs memory and loading time without adding views.
pub const VIDEO_FRAMES_PER_SECOND: f64 = 3.0;

/// The default stride of a Record3D export and why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VideoStride {
    /// Keep every `stride`-th frame.
    pub stride: usize,
    /// The video's frames a second (the metadata's `fps`).
    pub fps: f64,
    /// Frames in the export.
    pub frames: usize,
}

/// The fewest frames the default stride keeps: a field is not trained on
/// fewer views, however short the video.
pub const MIN_VIDEO_FRAMES: usize = 20;

/// The stride that keeps about [`VIDEO_FRAMES_PER_SECOND`] frames a
/// second of the export at `path`, from its metadata's `fps`, but at least
/// [`MIN_VIDEO_FRAMES`]; `None` when it states no rate or every frame is
/// kept anyway. An export without readable metadata is the reader's error.
pub fn default_stride(path: &Path) -> Result<Option<VideoStride>, DatasetError> {
    let (store, layout) = open(path)?;
    let Some(fps) = read_metadata(&store, layout)?.fps else {
        return Ok(None);
    };
    let frames = store.numbered(layout.images, layout.image_exts)?.len();
    let stride = ((fps / VIDEO_FRAMES_PER_SECOND).round().max(1.0) as usize)
        .min(frames / MIN_VIDEO_FRAMES)
        .max(1);
    Ok((stride > 1).then_some(VideoStride {
        stride,
        fps,
        frames,
    }))
}

/// The export's metadata (under the layout's name, or the other layout's).
fn read_metadata(store: &Store, layout: &Layout) -> Result<Metadata, DatasetError> {
    let name = [layout.metadata, "metadata.json", "metadata"]
        .into_iter()
        .find(|n| store.exists(n))
        .ok_or_else(|| {
            DatasetError::invalid(
                store.describe(layout.metadata),
                "missing: Record3D's metadata (intrinsics and poses) is not there",
            )
        })?;
    Metadata::parse(&store.read(name)?, &store.describe(name))
}

/// Reads the frames of a Record3D export: an EXR + JPG directory, a `.r3d`
/// file, or a directory of a `.r3d` file's contents.
pub fn read_capture(path: &Path) -> Result<Capture, DatasetError> {
    let (store, layout) = open(path)?;
    let meta = read_metadata(&store, layout)?;
    let meta_path = meta.path.clone();
    let images = store.numbered(layout.images, layout.image_exts)?;
    if images.is_empty() {
        return Err(DatasetError::invalid(
            store.describe(layout.images),
            format!("no images ({} named <i>.jpg)", layout.images),
        ));
    }
    let mut capture = Capture::default();
    for (&i, image) in &images {
        let pose = meta.pose(i, &store.describe(image))?;
        let depth_name = (layout.depth)(i);
        let conf_name = (layout.confidence)(i);
        let depth = store.exists(&depth_name).then(|| match layout.r3d {
            false => DepthSource::Exr(store.describe(&depth_name)),
            true => DepthSource::LzfseF32 {
                data: store.bytes(&depth_name),
                size: meta.depth_size,
            },
        });
        let confidence = store.exists(&conf_name).then(|| match layout.r3d {
            false => ConfidenceSource::Png(store.describe(&conf_name)),
            true => ConfidenceSource::LzfseU8(store.bytes(&conf_name)),
        });
        capture.frames.push(CaptureFrame {
            blur_score: None,
            name: format!("frame_{i:05}"),
            image: store.image(image),
            pose,
            pose_file: meta_path.clone(),
            intrinsics: meta.intrinsics,
            depth,
            confidence,
        });
    }
    let n = capture.frames.len();
    let unused = meta.pose_count().saturating_sub(n);
    if unused > 0 {
        capture.notes.push(format!(
            "{unused} of {} poses have no image",
            meta.pose_count()
        ));
    }
    capture.note_depth_coverage("the export");
    let with_depth = capture.frames.iter().any(|f| f.depth.is_some());
    if with_depth && meta.depth_size.is_none() && layout.r3d {
        capture.notes.push(
            "no `dw`/`dh` in the metadata: each depth map's size is inferred from its length"
                .into(),
        );
    }
    Ok(capture)
}
