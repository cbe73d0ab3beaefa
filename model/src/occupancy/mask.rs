//! Dilation of the grid's occupied cells.

/// `cells` (x fastest, then y, then z, `r` per axis) with every cell within
/// Chebyshev distance `radius` of a set cell set too. A box is separable, so
/// three passes of a one-axis maximum cost `O(cells * radius)`.
pub(super) fn dilate(cells: Vec<bool>, r: usize, radius: usize) -> Vec<bool> {
    if radius == 0 {
        return cells;
    }
    let mut cur = cells;
    for stride in [1, r, r * r] {
        let mut next = vec![false; cur.len()];
        for (c, out) in next.iter_mut().enumerate() {
            let along = c / stride % r;
            let lo = along.saturating_sub(radius);
            let hi = (along + radius).min(r - 1);
            let base = c - along * stride;
            *out = (lo..=hi).any(|a| cur[base + a * stride]);
        }
        cur = next;
    }
    cur
}
