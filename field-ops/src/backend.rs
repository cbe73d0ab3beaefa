//! From the `--backend` and `--device` flags to a Burn device, the same for
//! `train`, `eval` and the measurement programs (one clap group,
//! [`BackendArgs`]). Everything downstream takes a runtime [`Device`], so
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

/// Where the kernel cache was decided, once, before the first wgpu device.
#[cfg(feature = "wgpu")]
static KERNEL_CACHE: std::sync::OnceLock<crate::kernel_cache::KernelCache> =
    std::sync::OnceLock::new();

/// What the wgpu backend does in this build, for a program's first lines
/// (after the first wgpu device was made: where its kernel cache is).
pub fn wgpu_settings() -> String {
    #[cfg(feature = "wgpu")]
    let cache = KERNEL_CACHE
        .get()
        .map_or_else(|| "kernel cache not set up yet".into(), |c| c.describe());
    #[cfg(not(feature = "wgpu"))]
    let cache = String::from("not built");
    format!("wgpu: Burn's fusion on (chains of element-wise operations run as one kernel); {cache}")
}

#[cfg(feature = "wgpu")]
fn wgpu_device(index: Option<usize>) -> Device {
    use burn::tensor::DeviceKind;
    KERNEL_CACHE.get_or_init(crate::kernel_cache::configure);
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

/// Help of `--backend` (the variants explain themselves in `--help`).
const BACKEND_HELP: &str = "Compute backend: flex or ndarray on the CPU, wgpu on a GPU (on \
Linux through a Vulkan driver: a GPU's, or Mesa's lavapipe, which runs it on the CPU, slowly)";

/// Help of `--device`, the same wherever the flag is taken.
const DEVICE_HELP: &str = "Only with wgpu in --backend: the index (0, 1, ...) of the discrete \
GPU wgpu runs on [default: wgpu's default adapter, which is also how a software Vulkan driver is \
reached]. The CPU backends take no device: --device without wgpu is refused";

/// The compute device of a command: `--backend` and, for wgpu, `--device`.
/// `train`, every `eval` subcommand and the measurement programs that run
/// one backend flatten this group (`#[command(flatten)]`), so the two flags
/// are spelt, parsed, checked and explained the same everywhere.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::Args)]
pub struct BackendArgs {
    /// Compute backend.
    #[arg(long, value_enum, default_value_t = BackendKind::Flex, help = BACKEND_HELP)]
    pub backend: BackendKind,
    /// wgpu adapter index.
    #[arg(long, value_name = "INDEX", value_parser = parse_device_index, help = DEVICE_HELP)]
    pub device: Option<usize>,
}

impl BackendArgs {
    /// The Burn device of these flags (inference: no autodiff).
    pub fn device(&self) -> Device {
        device(self.backend, self.device)
    }

    /// Refuses `--device` with a backend other than wgpu, and `--backend
    /// wgpu` in a build without it ([`check_device_flag`]).
    pub fn check(&self) -> Result<(), String> {
        check_device_flag(self.backend, self.device)
    }

    /// The flags that give these settings to another program of this
    /// toolkit (`--backend NAME`, and `--device N` when set).
    pub fn to_args(&self) -> Vec<String> {
        let mut out = vec!["--backend".to_string(), self.backend.name().to_string()];
        if let Some(i) = self.device {
            out.extend(["--device".to_string(), i.to_string()]);
        }
        out
    }
}

/// [`BackendArgs`] for a measurement that times several backends in one
/// run (`bench`, `bench-vlm`): `--backend` takes a comma-separated list
/// (`--backends` is the same flag), and `--device` applies to wgpu's entry.
#[derive(Debug, Clone, PartialEq, Eq, clap::Args)]
pub struct BackendListArgs {
    /// Backends to measure, comma-separated.
    #[arg(
        long,
        alias = "backends",
        value_enum,
        value_delimiter = ',',
        default_values_t = [BackendKind::Flex, BackendKind::Ndarray],
        help = format!("Backends to measure, comma-separated, in this order. {BACKEND_HELP}")
    )]
    pub backend: Vec<BackendKind>,
    /// wgpu adapter index.
    #[arg(long, value_name = "INDEX", value_parser = parse_device_index, help = DEVICE_HELP)]
    pub device: Option<usize>,
}

impl BackendListArgs {
    /// The single-backend flags of `kind` from this list: `--device` goes
    /// to wgpu only.
    pub fn of(&self, kind: BackendKind) -> BackendArgs {
        BackendArgs {
            backend: kind,
            device: self.device.filter(|_| kind == BackendKind::Wgpu),
        }
    }

    /// Refuses `--device` when no backend of the list is wgpu, and wgpu in
    /// a build without it.
    pub fn check(&self) -> Result<(), String> {
        if self.device.is_some() && !self.backend.contains(&BackendKind::Wgpu) {
            return Err(
                "--device selects a wgpu adapter, but --backend lists no wgpu; add wgpu to it"
                    .into(),
            );
        }
        self.backend
            .iter()
            .try_for_each(|&kind| self.of(kind).check())
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

    #[test]
    fn backend_args_parse_check_and_give_the_flags_back() {
        use clap::Parser;
        #[derive(Parser)]
        struct One {
            #[command(flatten)]
            compute: BackendArgs,
        }
        #[derive(Parser)]
        struct Many {
            #[command(flatten)]
            compute: BackendListArgs,
        }
        let one = One::try_parse_from(["x"]).unwrap().compute;
        assert_eq!(one, BackendArgs::default());
        assert_eq!(one.to_args(), ["--backend", "flex"]);
        let one = One::try_parse_from(["x", "--backend", "wgpu", "--device", "1"])
            .unwrap()
            .compute;
        assert_eq!(one.to_args(), ["--backend", "wgpu", "--device", "1"]);
        assert_eq!(one.check().is_ok(), WGPU_BUILT);
        assert!(One::try_parse_from(["x", "--backend", "cuda"]).is_err());
        assert!(One::try_parse_from(["x", "--device", "gpu0"]).is_err());
        let e = One::try_parse_from(["x", "--device", "0"]).unwrap().compute;
        assert!(e.check().unwrap_err().contains("--backend wgpu"));

        let many = Many::try_parse_from(["x"]).unwrap().compute;
        assert_eq!(many.backend, [BackendKind::Flex, BackendKind::Ndarray]);
        assert!(many.check().is_ok());
        let many = Many::try_parse_from(["x", "--backends", "ndarray,wgpu", "--device", "2"])
            .unwrap()
            .compute;
        assert_eq!(many.of(BackendKind::Ndarray).device, None);
        assert_eq!(many.of(BackendKind::Wgpu).device, Some(2));
        assert_eq!(many.check().is_ok(), WGPU_BUILT);
        let many = Many::try_parse_from(["x", "--backend", "flex", "--device", "0"])
            .unwrap()
            .compute;
        assert!(many.check().unwrap_err().contains("no wgpu"));
    }
}
