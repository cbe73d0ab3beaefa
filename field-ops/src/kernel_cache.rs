//! Where the GPU backend (wgpu through CubeCL) keeps the kernels it
//! compiles and the autotune results it measures, so that a second run on
//! the same machine starts warm. CubeCL's own default is a `target/`
//! folder beside the outermost `Cargo.toml` above the working directory: a
//! run started from a fresh clone, or from anywhere else, would compile and
//! tune everything again. The user's cache folder (`~/.cache/cubecl` on
//! Linux) is shared by every run and clone instead. A CubeCL configuration
//! file of the user's (`cubecl.toml`, or a `[cubecl]` section of
//! `burn.toml`, in the working directory or above it) decides instead.

use std::path::{Path, PathBuf};

/// The file names CubeCL reads its configuration from.
pub const CONFIG_FILES: [&str; 4] = ["cubecl.toml", "CubeCL.toml", "burn.toml", "Burn.toml"];

/// Where this process's kernel cache is decided.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum KernelCache {
    /// In the user's cache folder (CubeCL's `global` setting).
    UserCache,
    /// By the user's configuration file at this path.
    UserFile(PathBuf),
    /// Already decided before this process asked (by a library that read
    /// CubeCL's configuration first).
    AlreadySet,
}

/// The first CubeCL configuration file in `dir` or above it.
pub fn config_file_above(dir: &Path) -> Option<PathBuf> {
    dir.ancestors()
        .flat_map(|d| CONFIG_FILES.iter().map(move |name| d.join(name)))
        .find(|p| p.is_file())
}

impl KernelCache {
    /// One line for the console.
    pub fn describe(&self) -> String {
        match self {
            KernelCache::UserCache => "compiled kernels and autotune results are kept in the \
                 user's cache folder (cubecl), so a second run starts warm"
                .into(),
            KernelCache::UserFile(p) => format!(
                "compiled kernels and autotune results are kept where {} says",
                p.display()
            ),
            KernelCache::AlreadySet => {
                "compiled kernels and autotune results are kept where CubeCL was told first".into()
            }
        }
    }
}

/// Points CubeCL's cache at the user's cache folder unless a configuration
/// file decides; call before the first wgpu device is made (later calls
/// report what the first decided). Environment variables (`CUBECL_*`,
/// e.g. `CUBECL_AUTOTUNE_LEVEL`) apply either way.
#[cfg(feature = "wgpu")]
pub fn configure() -> KernelCache {
    use burn::cubecl::config::cache::CacheConfig;
    use burn::cubecl::config::{CubeClRuntimeConfig, RuntimeConfig};
    let cwd = std::env::current_dir().unwrap_or_default();
    if let Some(file) = config_file_above(&cwd) {
        return KernelCache::UserFile(file);
    }
    let mut config = CubeClRuntimeConfig::default().override_from_env();
    config.environment.path = CacheConfig::Global;
    if CubeClRuntimeConfig::try_set(config) {
        KernelCache::UserCache
    } else {
        KernelCache::AlreadySet
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_configuration_file_in_the_directory_or_above_is_found() {
        let root = tempfile::tempdir().unwrap();
        let inner = root.path().join("a").join("b");
        std::fs::create_dir_all(&inner).unwrap();
        assert_eq!(config_file_above(&inner), None);
        std::fs::write(root.path().join("burn.toml"), "[cubecl]\n").unwrap();
        assert_eq!(
            config_file_above(&inner),
            Some(root.path().join("burn.toml"))
        );
        std::fs::write(inner.join("cubecl.toml"), "").unwrap();
        assert_eq!(config_file_above(&inner), Some(inner.join("cubecl.toml")));
        // A folder of that name is not a file.
        let other = root.path().join("c");
        std::fs::create_dir_all(other.join("cubecl.toml")).unwrap();
        assert_eq!(
            config_file_above(&other),
            Some(root.path().join("burn.toml"))
        );
        assert!(
            KernelCache::UserFile(inner.join("cubecl.toml"))
                .describe()
                .contains("cubecl.toml")
        );
    }
}
