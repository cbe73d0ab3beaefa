//! From the `--backend` flag to a Burn device. Everything downstream takes a
//! runtime [`Device`], so the one training step runs unchanged on each.

use burn::tensor::Device;

// One definition for both binaries, so `--backend` and `--device` mean the
// same in `train` and `eval`.
pub use field_ops::backend::{BackendKind, device};

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
