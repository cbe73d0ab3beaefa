//! What a training step measured: on the device ([`StepValues`]) until the
//! training loop reads a run of steps at once, then on the host
//! ([`StepReport`]).

use burn::tensor::Tensor;
use model::ClipStats;
use model::host_work::{ReadReason, read_back};

/// The values one step measured, still on the device: the total loss, the
/// fine colour MSE, the depth and open-set terms and the sum of absolute
/// gradients, as one `[5]` tensor; and what the occupancy grid clipped
/// (host numbers: the rays are clipped on the host).
#[derive(Debug, Clone)]
pub struct StepValues {
    values: Tensor<1>,
    /// What the occupancy grid clipped (`None` without a grid).
    pub clip: Option<ClipStats>,
}

/// Values a [`StepValues`] holds.
const VALUES: usize = 5;

impl StepValues {
    /// The values of `[total, rgb, depth, open, grad_l1]` (each `[1]`).
    pub fn new(values: [Tensor<1>; VALUES], clip: Option<ClipStats>) -> Self {
        Self {
            values: Tensor::cat(values.to_vec(), 0),
            clip,
        }
    }

    /// The values on the host (one read-back); `applied` is left false for
    /// the caller to set.
    pub fn read(self) -> StepReport {
        let clip = self.clip;
        let v = read_back(ReadReason::StepValues, self.values);
        StepReport::from_values(&v, clip)
    }

    /// Reads every step of `steps` with one read-back, in order.
    pub fn read_all(steps: Vec<StepValues>) -> Vec<StepReport> {
        if steps.is_empty() {
            return Vec::new();
        }
        let clips: Vec<_> = steps.iter().map(|s| s.clip).collect();
        let all = Tensor::cat(steps.into_iter().map(|s| s.values).collect(), 0);
        let v = read_back(ReadReason::StepValues, all);
        v.chunks(VALUES)
            .zip(clips)
            .map(|(v, clip)| StepReport::from_values(v, clip))
            .collect()
    }
}

/// What one step measured (host numbers).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport {
    /// Total loss.
    pub loss: f64,
    /// Fine colour MSE.
    pub rgb_mse: f64,
    /// Fine depth Huber.
    pub depth: f64,
    /// Open-set loss.
    pub open: f64,
    /// Sum of absolute gradient values over all parameters.
    pub grad_l1: f64,
    /// Whether the update was applied (false: non-finite loss or gradient).
    pub applied: bool,
    /// What the occupancy grid clipped (`None` without a grid).
    pub clip: Option<ClipStats>,
}

impl StepReport {
    fn from_values(v: &[f32], clip: Option<ClipStats>) -> Self {
        Self {
            loss: v[0] as f64,
            rgb_mse: v[1] as f64,
            depth: v[2] as f64,
            open: v[3] as f64,
            grad_l1: v[4] as f64,
            applied: false,
            clip,
        }
    }

    /// Whether the loss, its terms and the gradient were all finite (the
    /// step may be applied).
    pub fn finite(&self) -> bool {
        [self.loss, self.rgb_mse, self.depth, self.open, self.grad_l1]
            .iter()
            .all(|x| x.is_finite())
    }

    /// PSNR of the batch's fine colour.
    pub fn psnr(&self) -> f64 {
        crate::accuracy::psnr(self.rgb_mse)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;
    use model::host_work::read_backs;

    fn values(device: &Device, base: f32) -> StepValues {
        let one = |x: f32| Tensor::<1>::from_floats([x], device);
        StepValues::new(
            [
                one(base),
                one(base + 1.0),
                one(base + 2.0),
                one(base + 3.0),
                one(base + 4.0),
            ],
            None,
        )
    }

    #[test]
    fn a_run_of_steps_is_read_with_one_read_back_in_order() {
        let device = Device::flex();
        let steps = vec![
            values(&device, 0.0),
            values(&device, 10.0),
            values(&device, f32::NAN),
        ];
        let before = read_backs();
        let reports = StepValues::read_all(steps);
        let reads = read_backs().since(&before);
        assert_eq!(reads.of(ReadReason::StepValues), 1);
        assert_eq!(reads.total(), 1);
        assert_eq!(reports.len(), 3);
        assert_eq!(
            [
                reports[1].loss,
                reports[1].rgb_mse,
                reports[1].depth,
                reports[1].open,
                reports[1].grad_l1
            ],
            [10.0, 11.0, 12.0, 13.0, 14.0]
        );
        assert!(reports[0].finite() && reports[1].finite());
        assert!(!reports[2].finite() && reports[2].loss.is_nan());
        assert!(reports.iter().all(|r| !r.applied));
        assert!(StepValues::read_all(Vec::new()).is_empty());
        assert_eq!(
            read_backs().since(&before).total(),
            1,
            "nothing to read, no read"
        );
    }
}
