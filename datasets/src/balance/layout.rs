//! Where the balanced sampler's cells lie, kept as geometry instead of a
//! record per cell.
//!
//! A cell is the block of image pixels whose nearest map pixel is one map
//! pixel (so they share one target). A frame's cells form a grid: the
//! column of a cell is a span of image columns, its row a span of image
//! rows, and both are a pure function of the image size, the map size and
//! the interior. Frames with the same geometry share one [`Grid`], so a
//! cell is just its global index: frame slot, then grid row, then column
//! (the order in which the previous per-cell sampler listed them).

use std::collections::HashMap;

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::error::DatasetError;
use crate::features::{FeatureMap, FeatureSet};
use crate::sampler::interior;
use crate::scene::{Frame, Scene};

/// A map column (or row) `m` and the image pixels `[a, b)` of the interior
/// whose nearest map column is `m`: `(m, a, b)`.
pub(super) type Span = (u32, u32, u32);

/// The cell grid of every frame with one geometry.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Grid {
    /// Cell columns, left to right.
    pub xs: Vec<Span>,
    /// Cell rows, top to bottom.
    pub ys: Vec<Span>,
}

impl Grid {
    fn cells(&self) -> usize {
        self.xs.len() * self.ys.len()
    }
}

/// A frame sampled from: the scene frame, its grid and the global index of
/// its first cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FrameCells {
    pub frame: usize,
    pub grid: usize,
    pub first: usize,
}

/// One cell, located: the position of its frame in [`Layout::frames`] and
/// its column and row spans.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Located {
    pub slot: usize,
    pub x: Span,
    pub y: Span,
}

/// The cells of the frames sampled from, as one grid per frame geometry.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Layout {
    /// The frames, in the order given (a frame listed twice is sampled from
    /// twice, as before).
    pub frames: Vec<FrameCells>,
    /// Distinct grids.
    pub grids: Vec<Grid>,
    /// Cells in all (masked ones included); fits a `u32`.
    pub cells: usize,
}

/// For each map column (or row) `m` of a map `map_len` wide, the image
/// pixels `[a, b)` inside `[lo, hi)` whose nearest map pixel is `m`.
fn spans(image_len: u32, map_len: u32, lo: u32, hi: u32) -> Vec<Span> {
    let mut out: Vec<Span> = Vec::new();
    for p in lo..hi {
        let m = (((p as f64 + 0.5) * map_len as f64 / image_len as f64).floor() as u32)
            .min(map_len - 1);
        match out.last_mut() {
            Some(last) if last.0 == m => last.2 = p + 1,
            _ => out.push((m, p, p + 1)),
        }
    }
    out
}

/// The map of scene frame `fi`, `None` where it has none (or an empty one:
/// no pixel has a target there).
pub(super) fn map_of(fs: &FeatureSet, fi: usize) -> Option<&FeatureMap> {
    fs.maps.get(fi).filter(|m| m.width > 0 && m.height > 0)
}

impl Layout {
    /// The grids of `frames` (checked to be in range with non-empty
    /// images) inside `border_margin`. Fails when there are more cells than
    /// a `u32` counts (the sampler indexes cells with `u32`s).
    pub fn new(
        scene: &Scene,
        fs: &FeatureSet,
        frames: &[usize],
        border_margin: u32,
    ) -> Result<Self, DatasetError> {
        let mut keys: HashMap<[u32; 8], usize> = HashMap::new();
        let mut grids: Vec<Grid> = Vec::new();
        let mut slots = Vec::with_capacity(frames.len());
        let mut cells = 0usize;
        for &fi in frames {
            let frame = &scene.frames[fi];
            let (w, h) = (frame.rgb.width, frame.rgb.height);
            let ((x0, x1), (y0, y1)) = interior(border_margin, w, h);
            let (mw, mh) = map_of(fs, fi).map_or((w, h), |m| (m.width, m.height));
            let grid = *keys
                .entry([w, h, mw, mh, x0, x1, y0, y1])
                .or_insert_with(|| {
                    grids.push(Grid {
                        xs: spans(w, mw, x0, x1),
                        ys: spans(h, mh, y0, y1),
                    });
                    grids.len() - 1
                });
            slots.push(FrameCells {
                frame: fi,
                grid,
                first: cells,
            });
            cells += grids[grid].cells();
        }
        if cells > u32::MAX as usize {
            return Err(DatasetError::invalid(
                &scene.name,
                format!(
                    "{cells} feature-map cells to balance over; at most {} are supported",
                    u32::MAX
                ),
            ));
        }
        Ok(Self {
            frames: slots,
            grids,
            cells,
        })
    }

    /// Cell `cell` (below [`Layout::cells`]).
    pub fn locate(&self, cell: usize) -> Located {
        let slot = self.frames.partition_point(|f| f.first <= cell) - 1;
        let f = &self.frames[slot];
        let grid = &self.grids[f.grid];
        let local = cell - f.first;
        let cols = grid.xs.len();
        Located {
            slot,
            x: grid.xs[local % cols],
            y: grid.ys[local / cols],
        }
    }

    /// The scene frame of a located cell.
    pub fn frame<'a>(&self, scene: &'a Scene, at: &Located) -> (usize, &'a Frame) {
        let fi = self.frames[at.slot].frame;
        (fi, &scene.frames[fi])
    }

    /// Calls `f(cell, pixels)` for every cell with an unmasked pixel, in
    /// cell order, `pixels` its unmasked pixel count.
    pub fn visit(&self, scene: &Scene, mut f: impl FnMut(usize, u32)) {
        for fc in &self.frames {
            let frame = &scene.frames[fc.frame];
            let grid = &self.grids[fc.grid];
            let mut cell = fc.first;
            for &y in &grid.ys {
                for &x in &grid.xs {
                    let px = pixels(frame, x, y);
                    if px > 0 {
                        f(cell, px);
                    }
                    cell += 1;
                }
            }
        }
    }

    /// Heap bytes held.
    pub fn memory_bytes(&self) -> usize {
        let span = std::mem::size_of::<Span>();
        self.frames.capacity() * std::mem::size_of::<FrameCells>()
            + self.grids.capacity() * std::mem::size_of::<Grid>()
            + self
                .grids
                .iter()
                .map(|g| (g.xs.capacity() + g.ys.capacity()) * span)
                .sum::<usize>()
    }
}

/// Unmasked pixels of the cell spanning `x` and `y` of `frame`.
pub(super) fn pixels(frame: &Frame, x: Span, y: Span) -> u32 {
    match frame.mask {
        None => (x.2 - x.1) * (y.2 - y.1),
        Some(_) => (y.1..y.2)
            .map(|yy| {
                (x.1..x.2)
                    .filter(|&xx| frame.is_target_pixel(xx, yy))
                    .count() as u32
            })
            .sum(),
    }
}

/// Whether the cell spanning `x` and `y` of `frame` has an unmasked pixel
/// (stops at the first one).
pub(super) fn any_pixel(frame: &Frame, x: Span, y: Span) -> bool {
    frame.mask.is_none() || (y.1..y.2).any(|yy| (x.1..x.2).any(|xx| frame.is_target_pixel(xx, yy)))
}

/// Draws inside a cell before [`draw_in_cell`] turns to listing its
/// unmasked pixels.
const CELL_REJECTIONS: usize = 64;

/// A pixel of the cell spanning `x` and `y` of scene frame `fi`, uniformly
/// among its unmasked ones (drawn again while masked; a cell without a
/// mask keeps its first draw). The cell must have an unmasked pixel.
pub(super) fn draw_in_cell(
    rng: &mut ChaCha8Rng,
    scene: &Scene,
    fi: usize,
    x: Span,
    y: Span,
) -> (usize, u32, u32) {
    let frame = &scene.frames[fi];
    for _ in 0..CELL_REJECTIONS {
        let (px, py) = (rng.random_range(x.1..x.2), rng.random_range(y.1..y.2));
        if frame.is_target_pixel(px, py) {
            return (fi, px, py);
        }
    }
    let listed: Vec<(u32, u32)> = (y.1..y.2)
        .flat_map(|py| (x.1..x.2).map(move |px| (px, py)))
        .filter(|&(px, py)| frame.is_target_pixel(px, py))
        .collect();
    if listed.is_empty() {
        // Not reached: cells without an unmasked pixel are never drawn.
        return (fi, x.1, y.1);
    }
    let (px, py) = listed[rng.random_range(0..listed.len())];
    (fi, px, py)
}
