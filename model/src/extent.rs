//! The field's extent: the scene box, or an unbounded scene (Mip-NeRF 360's
//! contraction). One value owns everything that differs between the two:
//! how samples are spaced along a ray ([`Spacing`]), the bounds a ray is
//! rendered over ([`Extent::bound_rays`]), the Gaussians the MLPs encode
//! ([`Extent::frustums`], [`Extent::points`]) and whether the occupancy
//! grid applies ([`Extent::sampler_grid`]).
//!
//! A run saves its extent as `model.unbounded` (an [`UnboundedConfig`], or
//! none for the box); [`Extent::from_config`] builds the value from it.

use std::borrow::Cow;

use burn::tensor::Tensor;

use crate::geometry::NormalizedRay;
use crate::mip::{FrustumGaussians, cast_rays, frustum_means};
use crate::occupancy::OccupancyGrid;
use crate::rays::Rays;
use crate::sampling::stratified_t_vals;
use crate::stepfun::resample_t_vals;
use crate::unbounded::{UnboundedConfig, s_to_t, t_to_s};

/// Where the field lives.
#[derive(Debug, Clone, Default)]
pub enum Extent {
    /// The scene box (the normalised cube `[-pi, pi]^3`): rays carry its
    /// bounds, samples are spaced linearly in `t`, and the occupancy grid
    /// (which covers the box) applies.
    #[default]
    Box,
    /// An unbounded scene: rays run over the configuration's own bounds,
    /// samples are spaced in normalised disparity, Gaussians are pushed
    /// through the contraction, and no occupancy grid applies.
    Unbounded(UnboundedConfig),
}

/// Gaussians at point queries, `[n, 3]` each, in the coordinates the MLP
/// encodes.
#[derive(Debug, Clone)]
pub struct PointGaussians {
    /// Means, `[n, 3]`.
    pub mean: Tensor<2>,
    /// Diagonal of the covariances, `[n, 3]`.
    pub cov_diag: Tensor<2>,
}

impl Extent {
    /// The extent a saved configuration names: unbounded with `unbounded`,
    /// the box without it.
    pub fn from_config(unbounded: Option<&UnboundedConfig>) -> Extent {
        match unbounded {
            Some(u) => Extent::Unbounded(u.clone()),
            None => Extent::Box,
        }
    }

    /// The unbounded scene's configuration (`None`: the box).
    pub fn unbounded(&self) -> Option<&UnboundedConfig> {
        match self {
            Extent::Unbounded(u) => Some(u),
            Extent::Box => None,
        }
    }

    /// Whether the scene is unbounded.
    pub fn is_unbounded(&self) -> bool {
        matches!(self, Extent::Unbounded(_))
    }

    /// How `s`, the ray coordinate that samples are placed in, relates to
    /// `t`: normalised disparity in an unbounded scene, normalised distance
    /// in the box.
    pub fn spacing(&self) -> Spacing {
        match self {
            Extent::Unbounded(_) => Spacing::Disparity,
            Extent::Box => Spacing::Linear,
        }
    }

    /// The grid rendering samples with: `grid` in the box; none in an
    /// unbounded scene (a grid covers the scene box only, not contracted
    /// space).
    pub fn sampler_grid<'g>(&self, grid: Option<&'g OccupancyGrid>) -> Option<&'g OccupancyGrid> {
        match self {
            Extent::Unbounded(_) => None,
            Extent::Box => grid,
        }
    }

    /// The rays as this extent renders them: an unbounded scene replaces
    /// the bounds each ray carries (made for the scene box) with its own
    /// ([`UnboundedConfig::bound`]); the box keeps them.
    pub fn bound_rays<'r>(&self, rays: &'r [NormalizedRay]) -> Cow<'r, [NormalizedRay]> {
        match self {
            Extent::Unbounded(u) => rays.iter().map(|r| u.bound(r)).collect(),
            Extent::Box => Cow::Borrowed(rays),
        }
    }

    /// The frustums between consecutive fence posts as Gaussians in the
    /// coordinates the MLPs encode (contracted in an unbounded scene).
    ///
    /// # Shapes
    /// - `t_vals`: `[n, samples + 1]`; outputs: `[n, samples, 3]`.
    pub fn frustums(&self, t_vals: Tensor<2>, rays: &Rays) -> FrustumGaussians {
        let (o, d, r) = (
            rays.origins.clone(),
            rays.directions.clone(),
            rays.radii.clone(),
        );
        match self {
            Extent::Unbounded(u) => u.frustums(t_vals, o, d, r),
            Extent::Box => cast_rays(t_vals, o, d, r),
        }
    }

    /// The means of [`Extent::frustums`]' Gaussians alone, the same bits:
    /// what a field that reads no covariance needs.
    ///
    /// # Shapes
    /// - `t_vals`: `[n, samples + 1]`; output: `[n, samples, 3]`.
    pub fn frustum_means(&self, t_vals: Tensor<2>, rays: &Rays) -> Tensor<3> {
        let (o, d) = (rays.origins.clone(), rays.directions.clone());
        match self {
            Extent::Unbounded(u) => u.frustum_means(t_vals, o, d),
            Extent::Box => frustum_means(t_vals, o, d),
        }
    }

    /// Points (normalised frame) as isotropic Gaussians of standard
    /// deviation `radius`, in the coordinates the MLPs encode (contracted
    /// in an unbounded scene).
    ///
    /// # Shapes
    /// - `points`: `[n, 3]`; outputs: `[n, 3]`.
    pub fn points(&self, points: Tensor<2>, radius: f32) -> PointGaussians {
        match self {
            Extent::Unbounded(u) => {
                let g = u.points(points, radius);
                let [n, _, _] = g.mean.dims();
                PointGaussians {
                    mean: g.mean.reshape([n, 3]),
                    cov_diag: g.cov_diag.reshape([n, 3]),
                }
            }
            Extent::Box => PointGaussians {
                cov_diag: points.zeros_like().add_scalar(radius * radius),
                mean: points,
            },
        }
    }
}

/// `s`, a ray's normalised coordinate, of metric `t` under `spacing`, and
/// back: normalised disparity for an unbounded field (so that samples
/// spread over near and far content as a pixel resolves them), normalised
/// distance otherwise.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Spacing {
    /// `s = (t - near) / (far - near)`.
    Linear,
    /// `s = (1/t - 1/near) / (1/far - 1/near)` (see
    /// [`crate::unbounded::t_to_s`]).
    Disparity,
}

impl Spacing {
    /// Metric `t` to `s`.
    ///
    /// # Shapes
    /// - `t`: `[rays, k]`; `near`, `far`: `[rays, 1]`; output: like `t`.
    pub fn t_to_s(self, t: Tensor<2>, near: Tensor<2>, far: Tensor<2>) -> Tensor<2> {
        match self {
            Spacing::Linear => t.sub(near.clone()).div(far.sub(near).clamp_min(1e-20)),
            Spacing::Disparity => t_to_s(t, near, far),
        }
    }

    /// `s` back to metric `t`.
    ///
    /// # Shapes
    /// - `s`: `[rays, k]`; `near`, `far`: `[rays, 1]`; output: like `s`.
    pub fn s_to_t(self, s: Tensor<2>, near: Tensor<2>, far: Tensor<2>) -> Tensor<2> {
        match self {
            Spacing::Linear => near.clone().add(far.sub(near).mul(s)),
            Spacing::Disparity => s_to_t(s, near, far),
        }
    }

    /// `samples + 1` stratified posts between `near` and `far`: evenly
    /// spaced in `t` ([`Spacing::Linear`]) or in `s` and mapped to `t`.
    ///
    /// # Shapes
    /// - `near`, `far`: `[rays, 1]`; output: `[rays, samples + 1]` (metric `t`).
    pub fn stratified(
        self,
        near: Tensor<2>,
        far: Tensor<2>,
        samples: usize,
        randomized: bool,
    ) -> Tensor<2> {
        match self {
            Spacing::Linear => stratified_t_vals(near, far, samples, randomized),
            Spacing::Disparity => {
                let s = stratified_t_vals(near.zeros_like(), far.ones_like(), samples, randomized);
                self.s_to_t(s, near, far)
            }
        }
    }

    /// Mip-NeRF's blur-resample of `weights` on the posts `t` (see
    /// [`resample_t_vals`]), in `t` ([`Spacing::Linear`]) or in `s`.
    ///
    /// # Shapes
    /// - `t`: `[rays, samples + 1]`; `weights`: `[rays, samples]`; `near`,
    ///   `far`: `[rays, 1]`; output: like `t` (metric `t`).
    pub fn resampled(
        self,
        t: Tensor<2>,
        weights: Tensor<2>,
        near: Tensor<2>,
        far: Tensor<2>,
        padding: f32,
        randomized: bool,
    ) -> Tensor<2> {
        match self {
            Spacing::Linear => resample_t_vals(t, weights, padding, randomized),
            Spacing::Disparity => {
                let s = self.t_to_s(t, near.clone(), far.clone());
                let s = resample_t_vals(s, weights, padding, randomized);
                self.s_to_t(s, near, far)
            }
        }
    }
}
