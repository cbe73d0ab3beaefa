//! `--dataset`: which scene a command reads, the same for `train` and
//! `eval extract`: the built-in synthetic room, a format on disk (each
//! [`Format`], named and described as it names and describes itself), or
//! the format detected from the files.

use std::sync::OnceLock;

use clap::builder::PossibleValue;
use datasets::detect::Format;

/// Which kind of scene to read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DatasetArg {
    /// The built-in generated room (no files needed).
    Synthetic,
    /// A scene on disk in this format.
    Disk(Format),
    /// Detect the format from the files in `--data` (and print which).
    Auto,
}

impl DatasetArg {
    /// The format on disk this names (`None` for `synthetic` and `auto`).
    pub fn format(self) -> Option<Format> {
        match self {
            Self::Disk(format) => Some(format),
            Self::Synthetic | Self::Auto => None,
        }
    }

    /// Lower-case name as used on the command line and in run names.
    pub fn name(self) -> &'static str {
        match self {
            Self::Synthetic => "synthetic",
            Self::Disk(format) => format.name(),
            Self::Auto => "auto",
        }
    }
}

impl clap::ValueEnum for DatasetArg {
    fn value_variants<'a>() -> &'a [Self] {
        static ALL: OnceLock<Vec<DatasetArg>> = OnceLock::new();
        ALL.get_or_init(|| {
            std::iter::once(Self::Synthetic)
                .chain(Format::ALL.map(Self::Disk))
                .chain(std::iter::once(Self::Auto))
                .collect()
        })
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        let help = match self {
            Self::Synthetic => "The built-in generated room (no files needed)".to_string(),
            Self::Disk(f) => format!("{}: {}", f.description(), f.needs()),
            Self::Auto => "Detect the format from the files in `--data` (and print which)".into(),
        };
        Some(PossibleValue::new(self.name()).help(help))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    #[test]
    fn every_format_is_a_choice_spelled_as_the_format_names_itself() {
        assert_eq!(DatasetArg::value_variants().len(), Format::ALL.len() + 2);
        for format in Format::ALL {
            let arg = DatasetArg::Disk(format);
            assert!(DatasetArg::value_variants().contains(&arg));
            assert_eq!(arg.name(), format.name());
            assert_eq!(arg.format(), Some(format));
            assert_eq!(DatasetArg::from_str(format.name(), false), Ok(arg));
        }
        for (arg, name) in [
            (DatasetArg::Synthetic, "synthetic"),
            (DatasetArg::Auto, "auto"),
        ] {
            assert_eq!(arg.format(), None);
            assert_eq!(DatasetArg::from_str(name, false), Ok(arg));
        }
        assert!(DatasetArg::from_str("scanner_app", false).is_err());
        let help = DatasetArg::Disk(Format::Colmap)
            .to_possible_value()
            .and_then(|v| v.get_help().map(|h| h.to_string()))
            .expect("a help text");
        assert!(
            help.starts_with("A COLMAP reconstruction: sparse/0/"),
            "{help}"
        );
    }
}
