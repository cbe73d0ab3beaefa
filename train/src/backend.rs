//! From the `--backend` flag to a Burn device. Everything downstream takes a
//! runtime [`Device`], so the one training step runs unchanged on each.

use burn::tensor::{Device, DeviceKind};
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
        BackendKind::Wgpu => Device::wgpu(match index {
            Some(i) => DeviceKind::DiscreteGpu(i),
            None => DeviceKind::DefaultDevice,
        }),
    }
}

/// The training device: [`device`] with autodiff enabled.
pub fn training_device(kind: BackendKind, index: Option<usize>) -> Device {
    device(kind, index).autodiff()
}

/// Whether a Vulkan driver manifest is installed (the wgpu backend needs
/// one; without it wgpu falls back to OpenGL, which deadlocks on software
/// renderers).
pub fn vulkan_available() -> bool {
    ["/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d"]
        .iter()
        .any(|dir| {
            std::fs::read_dir(dir)
                .map(|entries| {
                    entries
                        .flatten()
                        .any(|e| e.path().extension().and_then(|x| x.to_str()) == Some("json"))
                })
                .unwrap_or(false)
        })
}

/// Peak resident memory of this process in bytes (`VmHWM` from
/// `/proc/self/status`), or `None` where that file does not exist.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    parse_vm_hwm(&status)
}

/// Parses the `VmHWM:   1234 kB` line of a `/proc/<pid>/status` text.
pub fn parse_vm_hwm(status: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let mut parts = line["VmHWM:".len()..].split_whitespace();
    let value: u64 = parts.next()?.parse().ok()?;
    let scale = match parts.next().unwrap_or("kB") {
        "kB" => 1024,
        "mB" | "MB" => 1024 * 1024,
        _ => 1,
    };
    Some(value * scale)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Tensor;

    #[test]
    fn vm_hwm_parses_kilobytes() {
        let s = "Name:\tx\nVmPeak:\t  999 kB\nVmHWM:\t    2048 kB\nVmRSS:\t 1 kB\n";
        assert_eq!(parse_vm_hwm(s), Some(2048 * 1024));
        assert_eq!(parse_vm_hwm("VmRSS: 1 kB"), None);
        if std::path::Path::new("/proc/self/status").exists() {
            assert!(peak_memory_bytes().unwrap() > 1 << 20);
        }
    }

    #[test]
    fn cpu_devices_compute_and_track_gradients() {
        for kind in [BackendKind::Flex, BackendKind::Ndarray] {
            let d = training_device(kind, None);
            assert!(d.is_autodiff());
            let x = Tensor::<1>::from_floats([1.0, 2.0, 3.0], &d).require_grad();
            let loss = (x.clone() * x.clone()).sum();
            let grads = loss.backward();
            let g: Vec<f32> = x
                .grad(&grads)
                .unwrap()
                .into_data()
                .try_to_vec::<f32>()
                .unwrap();
            assert_eq!(g, vec![2.0, 4.0, 6.0], "{kind}");
        }
    }
}
