//! From the `--backend` and `--device` flags to a Burn device, the same for
//! `train` and `eval`. Everything downstream takes a runtime [`Device`], so
//! rendering and training run unchanged on each backend.

use burn::tensor::Device;
use serde::{Deserialize, Serialize};

/// The compute backends this build supports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum BackendKind {
    /// Burn's pure-Rust CPU backend (fastest on the CPU).
    #[default]
    Flex,
    /// The ndarray CPU backend (reference; slower).
    Ndarray,
    /// wgpu (Vulkan / Metal / DX12), a GPU or a software Vulkan driver.
    Wgpu,
}

impl BackendKind {
    /// Lower-case name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Flex => "flex",
            Self::Ndarray => "ndarray",
            Self::Wgpu => "wgpu",
        }
    }
}

impl std::fmt::Display for BackendKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The inference device (no autodiff) for `kind`. For wgpu, `index` picks
/// the discrete GPU with that index; without it wgpu's default adapter is
/// used (which is also how a software Vulkan driver is reached). The device
/// is always chosen explicitly: with the wgpu feature compiled in, Burn's
/// `Device::default()` would silently pick wgpu.
pub fn device(kind: BackendKind, index: Option<usize>) -> Device {
    match kind {
        BackendKind::Flex => Device::flex(),
        #[allow(deprecated)] // ndarray is kept as a reference backend on purpose
        BackendKind::Ndarray => Device::ndarray(),
        BackendKind::Wgpu => wgpu_device(index),
    }
}

/// Whether this build has the wgpu backend (the default `wgpu` feature).
pub const WGPU_BUILT: bool = cfg!(feature = "wgpu");

#[cfg(feature = "wgpu")]
fn wgpu_device(index: Option<usize>) -> Device {
    use burn::tensor::DeviceKind;
    Device::wgpu(match index {
        Some(i) => DeviceKind::DiscreteGpu(i),
        None => DeviceKind::DefaultDevice,
    })
}

/// A CPU-only build has no wgpu device; the command lines refuse `--backend
/// wgpu` before this is reached ([`check_device_flag`]), so a library
/// caller is the only one who gets here, and is told.
#[cfg(not(feature = "wgpu"))]
fn wgpu_device(_index: Option<usize>) -> Device {
    eprintln!(
        "warning: this build has no wgpu backend (built without the `wgpu` feature); using flex"
    );
    Device::flex()
}

/// Parses `--device`: the index of a wgpu adapter. A backend name is
/// answered with the flag that chooses backends, since older versions of
/// `eval` took one here.
pub fn parse_device_index(s: &str) -> Result<usize, String> {
    if let Ok(i) = s.trim().parse::<usize>() {
        return Ok(i);
    }
    if ["flex", "ndarray", "wgpu"].contains(&s.trim()) {
        return Err(format!(
            "--device takes the index of a wgpu adapter (as in train); choose the backend with --backend {s}"
        ));
    }
    Err(format!(
        "expected a wgpu adapter index (0, 1, ...), got {s:?}"
    ))
}

/// Refuses `--device` without `--backend wgpu` (it would be ignored), and
/// `--backend wgpu` in a build without the wgpu backend.
pub fn check_device_flag(kind: BackendKind, index: Option<usize>) -> Result<(), String> {
    if kind == BackendKind::Wgpu && !WGPU_BUILT {
        return Err(
            "--backend wgpu: this build has no wgpu backend (it was built with \
             --no-default-features); build without that flag to use a GPU"
                .into(),
        );
    }
    match (kind, index) {
        (BackendKind::Wgpu, _) | (_, None) => Ok(()),
        (k, Some(_)) => Err(format!(
            "--device selects a wgpu adapter, but the backend is {k}; add --backend wgpu"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_flag_parses_indices_and_points_backend_names_to_backend() {
        assert_eq!(parse_device_index("1"), Ok(1));
        let e = parse_device_index("ndarray").unwrap_err();
        assert!(e.contains("--backend ndarray"), "{e}");
        assert!(parse_device_index("gpu0").is_err());
        assert!(check_device_flag(BackendKind::Flex, Some(0)).is_err());
        assert_eq!(
            check_device_flag(BackendKind::Wgpu, Some(0)).is_ok(),
            WGPU_BUILT
        );
        assert!(check_device_flag(BackendKind::Flex, None).is_ok());
    }
}
