//! `--dataset`: which scene a command reads, the same for `train` and
//! `eval extract`. Each format on disk is a [`Format`], spelled as
//! [`Format::name`] says; `synthetic` and `auto` are the two choices that
//! are not a format.

use datasets::detect::Format;

/// Which kind of scene to read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DatasetArg {
    /// The built-in generated room (no files needed).
    Synthetic,
    /// Nice-SLAM Replica (`results/`, `traj.txt`, `cam_params.json`).
    Replica,
    /// Blender / nerfstudio `transforms*.json`.
    Blender,
    /// LLFF `poses_bounds.npy` with `images_N/`.
    Llff,
    /// A COLMAP reconstruction (`images/`, `sparse/0/` or `sparse/`, binary
    /// or text model).
    Colmap,
    /// A ScanNet scene export (`color/`, `depth/`, `pose/`, `intrinsic/`).
    Scannet,
    /// A 3D Scanner App "All Data" export (`frame_NNNNN.jpg` + `.json`,
    /// `depth_NNNNN.png`, `conf_NNNNN.png`, `textured_output.obj`).
    ScannerApp,
    /// A Record3D export: EXR + JPG (`metadata.json`, `rgb/`, `depth/`) or
    /// R3D (the `.r3d` file, or its unzipped `metadata` and `rgbd/`).
    Record3d,
    /// A Polycam raw-data export (`keyframes/` with `images/`, `cameras/`,
    /// `depth/`, `confidence/`; `corrected_*` where present).
    Polycam,
    /// Detect the format from the files in `--data` (and print which).
    Auto,
}

impl DatasetArg {
    /// The format on disk this names (`None` for `synthetic` and `auto`).
    pub fn format(self) -> Option<Format> {
        match self {
            Self::Synthetic | Self::Auto => None,
            Self::Replica => Some(Format::Replica),
            Self::Blender => Some(Format::Blender),
            Self::Llff => Some(Format::Llff),
            Self::Colmap => Some(Format::Colmap),
            Self::Scannet => Some(Format::Scannet),
            Self::ScannerApp => Some(Format::ScannerApp),
            Self::Record3d => Some(Format::Record3d),
            Self::Polycam => Some(Format::Polycam),
        }
    }

    /// Lower-case name as used on the command line and in run names.
    pub fn name(self) -> &'static str {
        match self {
            Self::Synthetic => "synthetic",
            Self::Auto => "auto",
            other => other.format().map_or("auto", Format::name),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    #[test]
    fn every_format_is_a_choice_spelled_as_the_format_names_itself() {
        for format in Format::ALL {
            let arg = DatasetArg::value_variants()
                .iter()
                .copied()
                .find(|a| a.format() == Some(format))
                .unwrap_or_else(|| panic!("{format} is a --dataset choice"));
            let spelled = arg.to_possible_value().expect("not hidden");
            assert_eq!(spelled.get_name(), format.name());
            assert_eq!(arg.name(), format.name());
            assert_eq!(DatasetArg::from_str(format.name(), false), Ok(arg));
        }
        assert_eq!(DatasetArg::value_variants().len(), Format::ALL.len() + 2);
        for (arg, name) in [
            (DatasetArg::Synthetic, "synthetic"),
            (DatasetArg::Auto, "auto"),
        ] {
            assert_eq!(arg.format(), None);
            assert_eq!(arg.name(), name);
            assert_eq!(arg.to_possible_value().unwrap().get_name(), name);
        }
    }
}
