//! Which format a scene directory is in, from the files it holds: what
//! `--dataset auto` runs.

use std::fmt;
use std::path::Path;

use crate::error::DatasetError;

/// A scene format on disk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Nice-SLAM Replica.
    Replica,
    /// Blender / nerfstudio `transforms.json`.
    Blender,
    /// LLFF `poses_bounds.npy`.
    Llff,
    /// A COLMAP reconstruction.
    Colmap,
    /// A ScanNet scene export.
    Scannet,
    /// A 3D Scanner App "All Data" export.
    ScannerApp,
    /// A Record3D export (EXR + JPG, or R3D).
    Record3d,
    /// A Polycam raw-data export.
    Polycam,
}

impl Format {
    /// Every format, in the order their requirements are listed.
    pub const ALL: [Format; 8] = [
        Format::Colmap,
        Format::Blender,
        Format::Scannet,
        Format::Replica,
        Format::Llff,
        Format::ScannerApp,
        Format::Record3d,
        Format::Polycam,
    ];

    /// The name used on the command line and in `scene.json`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Replica => "replica",
            Self::Blender => "blender",
            Self::Llff => "llff",
            Self::Colmap => "colmap",
            Self::Scannet => "scannet",
            Self::ScannerApp => "scanner-app",
            Self::Record3d => "record3d",
            Self::Polycam => "polycam",
        }
    }

    /// This format's loader with its default options.
    pub fn default_loader(self) -> crate::LoaderOptions {
        use crate::LoaderOptions as L;
        match self {
            Self::Replica => L::Replica(Default::default()),
            Self::Blender => L::Blender(Default::default()),
            Self::Llff => L::Llff(Default::default()),
            Self::Colmap => L::Colmap(Default::default()),
            Self::Scannet => L::Scannet(Default::default()),
            Self::ScannerApp => L::ScannerApp(Default::default()),
            Self::Record3d => L::Record3d(Default::default()),
            Self::Polycam => L::Polycam(Default::default()),
        }
    }

    /// Whether this is a phone capture (ARKit poses, LiDAR depth).
    pub fn is_phone(self) -> bool {
        matches!(self, Self::ScannerApp | Self::Record3d | Self::Polycam)
    }

    /// What this format is, in a few words (for `--help`).
    pub fn description(self) -> &'static str {
        match self {
            Self::Replica => "Nice-SLAM Replica",
            Self::Blender => "Blender / nerfstudio transforms",
            Self::Llff => "LLFF",
            Self::Colmap => "A COLMAP reconstruction",
            Self::Scannet => "A ScanNet scene export",
            Self::ScannerApp => "A 3D Scanner App \"All Data\" export",
            Self::Record3d => "A Record3D export",
            Self::Polycam => "A Polycam raw-data export",
        }
    }

    /// What a directory of this format holds, for messages.
    pub fn needs(self) -> &'static str {
        match self {
            Self::Replica => "traj.txt and results/ (frameNNNNNN.jpg, depthNNNNNN.png)",
            Self::Blender => "transforms.json or transforms_train.json",
            Self::Llff => "poses_bounds.npy and images*/",
            Self::Colmap => {
                "sparse/0/ or sparse/ with cameras, images and points3D (.bin or .txt), and images/"
            }
            Self::Scannet => "color/, depth/, pose/ and intrinsic/intrinsic_color.txt",
            Self::ScannerApp => "frame_NNNNN.jpg with frame_NNNNN.json (3D Scanner App, All Data)",
            Self::Record3d => {
                "metadata.json with rgb/ (EXR + JPG), or metadata with rgbd/ (an unzipped .r3d), \
                 or a .r3d file"
            }
            Self::Polycam => {
                "keyframes/ with images/ and cameras/ (or corrected_*), or is keyframes/"
            }
        }
    }

    /// The files of `dir` that show it is in this format, or `None`.
    fn evidence(self, dir: &Path) -> Option<String> {
        let is_file = |p: &str| dir.join(p).is_file();
        let is_dir = |p: &str| dir.join(p).is_dir();
        match self {
            Self::Replica => (is_file("traj.txt") && is_dir("results"))
                .then(|| "traj.txt and results/".to_string()),
            Self::Blender => ["transforms.json", "transforms_train.json"]
                .into_iter()
                .find(|f| is_file(f))
                .map(str::to_string),
            Self::Llff => is_file("poses_bounds.npy").then(|| "poses_bounds.npy".to_string()),
            Self::Colmap => ["sparse/0", "sparse"].into_iter().find_map(|s| {
                ["cameras.bin", "cameras.txt"]
                    .into_iter()
                    .find(|c| is_file(&format!("{s}/{c}")))
                    .map(|c| format!("{s}/{c}"))
            }),
            Self::Scannet => {
                (is_dir("color") && is_dir("pose") && is_file("intrinsic/intrinsic_color.txt"))
                    .then(|| "color/, pose/ and intrinsic/intrinsic_color.txt".to_string())
            }
            // The app writes a pose for every frame and an image only for
            // its keyframes, which need not include the first.
            Self::ScannerApp => named(dir, "frame_", "json").into_iter().find_map(|json| {
                let stem = json.trim_end_matches(".json").to_string();
                ["jpg", "jpeg", "png"]
                    .into_iter()
                    .find(|e| is_file(&format!("{stem}.{e}")))
                    .map(|e| format!("{json} with {stem}.{e}"))
            }),
            Self::Record3d => {
                if is_file("metadata.json") && is_dir("rgb") {
                    Some("metadata.json and rgb/".into())
                } else if is_file("metadata") && is_dir("rgbd") {
                    Some("metadata and rgbd/".into())
                } else {
                    None
                }
            }
            Self::Polycam => ["keyframes/", ""].into_iter().find_map(|k| {
                ["images", "corrected_images"].into_iter().find_map(|i| {
                    let cams = i.replace("images", "cameras");
                    (is_dir(&format!("{k}{i}")) && is_dir(&format!("{k}{cams}")))
                        .then(|| format!("{k}{i}/ and {k}{cams}/"))
                })
            }),
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The format `dir` was found to be in, and the files that decided it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Detected {
    /// The format.
    pub format: Format,
    /// The files that show it (e.g. `sparse/0/cameras.bin`).
    pub evidence: String,
}

/// The names of the files of `dir` called `<prefix><digits>.<ext>`, in
/// name order.
fn named(dir: &Path, prefix: &str, ext: &str) -> Vec<String> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut names: Vec<String> = entries
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| {
            n.strip_prefix(prefix)
                .and_then(|r| r.strip_suffix(&format!(".{ext}")))
                .is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
        })
        .collect();
    names.sort();
    names
}

/// Detects the format of the scene directory `dir`: exactly one format's
/// files must be there. An unknown or empty directory, or one that holds
/// the files of several formats, is an error listing what each format needs.
/// A `.r3d` file (Record3D's archive) is the one scene that is a file.
pub fn detect(dir: &Path) -> Result<Detected, DatasetError> {
    if dir.is_file()
        && dir
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("r3d"))
    {
        return Ok(Detected {
            format: Format::Record3d,
            evidence: "a .r3d archive".into(),
        });
    }
    if !dir.is_dir() {
        return Err(DatasetError::invalid(
            dir,
            "not a directory (--data takes the scene directory)",
        ));
    }
    let found: Vec<Detected> = Format::ALL
        .into_iter()
        .filter_map(|format| {
            format
                .evidence(dir)
                .map(|evidence| Detected { format, evidence })
        })
        .collect();
    match found.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err(DatasetError::invalid(
            dir,
            format!(
                "no scene format recognised; a scene directory holds one of:\n{}",
                requirements()
            ),
        )),
        many => Err(DatasetError::invalid(
            dir,
            format!(
                "holds the files of several formats ({}); choose one with --dataset {}",
                many.iter()
                    .map(|d| format!("{}: {}", d.format, d.evidence))
                    .collect::<Vec<_>>()
                    .join("; "),
                many.iter()
                    .map(|d| d.format.name())
                    .collect::<Vec<_>>()
                    .join("|"),
            ),
        )),
    }
}

/// One line per format: its name and what its directory holds.
fn requirements() -> String {
    Format::ALL
        .iter()
        .map(|f| format!("  {:<11} {}", f.name(), f.needs()))
        .collect::<Vec<_>>()
        .join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn touch(dir: &Path, rel: &str) {
        let p = dir.join(rel);
        std::fs::create_dir_all(p.parent().expect("parent")).expect("mkdir");
        std::fs::write(p, b"").expect("write");
    }

    #[test]
    fn each_layout_is_recognised_and_mixtures_are_refused() {
        let cases: [(&[&str], Format); 11] = [
            (&["frame_00003.json", "frame_00003.jpg"], Format::ScannerApp),
            (
                &["metadata.json", "rgb/0.jpg", "depth/0.exr"],
                Format::Record3d,
            ),
            (&["metadata", "rgbd/0.jpg"], Format::Record3d),
            (
                &["keyframes/images/1.jpg", "keyframes/cameras/1.json"],
                Format::Polycam,
            ),
            (
                &["corrected_images/1.jpg", "corrected_cameras/1.json"],
                Format::Polycam,
            ),
            (&["traj.txt", "results/frame000000.jpg"], Format::Replica),
            (&["transforms.json"], Format::Blender),
            (&["poses_bounds.npy", "images_8/a.png"], Format::Llff),
            (&["sparse/0/cameras.bin", "images/a.jpg"], Format::Colmap),
            (&["sparse/cameras.txt", "images/a.jpg"], Format::Colmap),
            (
                &["color/0.jpg", "pose/0.txt", "intrinsic/intrinsic_color.txt"],
                Format::Scannet,
            ),
        ];
        for (files, want) in cases {
            let dir = tempfile::tempdir().expect("temp dir");
            files.iter().for_each(|f| touch(dir.path(), f));
            assert_eq!(
                detect(dir.path()).expect("detected").format,
                want,
                "{files:?}"
            );
        }
        let dir = tempfile::tempdir().expect("temp dir");
        let e = detect(dir.path()).expect_err("empty").to_string();
        assert!(
            e.contains("no scene format") && e.contains("poses_bounds.npy"),
            "{e}"
        );
        touch(dir.path(), "transforms.json");
        touch(dir.path(), "sparse/0/cameras.bin");
        let e = detect(dir.path()).expect_err("two formats").to_string();
        assert!(e.contains("--dataset colmap|blender"), "{e}");
        // A pose without its image is not yet a 3D Scanner App export.
        let lone = tempfile::tempdir().expect("temp dir");
        touch(lone.path(), "frame_00000.json");
        assert!(detect(lone.path()).is_err());
        let r3d = dir.path().join("scan.r3d");
        std::fs::write(&r3d, b"").expect("write");
        assert_eq!(detect(&r3d).expect("r3d").format, Format::Record3d);
        let e = detect(&dir.path().join("transforms.json"))
            .expect_err("a file")
            .to_string();
        assert!(e.contains("not a directory"), "{e}");
    }
}
