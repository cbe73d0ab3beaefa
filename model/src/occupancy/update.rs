//! The grid's refresh from the field's density.

use burn::tensor::{Tensor, TensorData};

use super::OccupancyGrid;
use crate::host_work::{ReadReason, read_back};
use crate::nerf::OpenNerf;

/// Points per density query of an update (bounds the peak memory).
const QUERY_CHUNK: usize = 8192;

impl OccupancyGrid {
    /// Refreshes the grid from `field` (an inference model, see
    /// `Module::valid`, on its own device): the density at the grid's
    /// jittered points of this update (several per cell during the early
    /// updates, one after, see [`OccupancyGrid::sample_points`]), drawn from
    /// `seed`, is folded in (see [`OccupancyGrid::update`]). Each point is
    /// encoded as a Gaussian of a quarter cell (the scale the samples
    /// crossing the cell are seen at); the points are queried
    /// 8192 at a time.
    pub fn update_from_field(&mut self, field: &OpenNerf, seed: u64) {
        let points = self.sample_points(seed);
        let radius = 0.25 * self.cell_size() as f32;
        let device = field.device();
        let mut density = Vec::with_capacity(points.len());
        for part in points.chunks(QUERY_CHUNK) {
            let flat: Vec<f32> = part.iter().flatten().copied().collect();
            let p = Tensor::<2>::from_data(TensorData::new(flat, [part.len(), 3]), &device);
            let d = field.query_density(p, radius);
            density.extend(read_back(ReadReason::OccupancyUpdate, d));
        }
        self.update(&density);
    }
}
