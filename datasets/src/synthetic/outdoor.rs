//! The outdoor scene: a few objects on a ground plane under a distant
//! backdrop, built from the room's labelled boxes (an unbounded capture at
//! the size of the CI room).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::room::{Builder, Room};

/// Half-width of the outdoor scene's backdrop (walls this far from the
/// middle on every side, a sky as high), metres.
pub const OUTDOOR_BACKDROP: f64 = 12.0;

/// Objects of the outdoor scene within this distance of the middle (on the
/// ground plane) are its centre piece; the rest stand around it.
pub const OUTDOOR_CENTRE: f64 = 1.5;

/// The outdoor scene of a seed: a small table with a bowl, a bottle and a
/// book, a chair and a potted plant in the middle of a ground plane (within
/// [`OUTDOOR_CENTRE`] of it), ten pillars 4.5 to 7 m around them, a ring of
/// twelve painted panels 10.5 m out and a backdrop [`OUTDOOR_BACKDROP`]
/// metres away on every side and as high: an object captured from a ring
/// of cameras whose views reach far past it (an unbounded capture), with
/// content at every distance.
pub fn build_outdoor(seed: u64) -> Room {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0d00_5eed);
    let mut j = |a: f64| rng.random_range(-a..a);
    let mut b = Builder {
        primitives: Vec::new(),
        groups: Vec::new(),
    };
    let (tx, ty, th) = (0.35 + j(0.03), 0.25 + j(0.03), 0.55);
    let mut table = vec![("table", [-tx, -ty, th - 0.04], [tx, ty, th])];
    for (sx, sy) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
        let (lx, ly) = (sx * (tx - 0.05), sy * (ty - 0.05));
        table.push((
            "table",
            [lx - 0.03, ly - 0.03, 0.0],
            [lx + 0.03, ly + 0.03, th - 0.04],
        ));
    }
    b.object(&table);
    let (bx, by) = (-0.12 + j(0.04), 0.05 + j(0.04));
    b.object(&[(
        "bowl",
        [bx - 0.09, by - 0.09, th],
        [bx + 0.09, by + 0.09, th + 0.07],
    )]);
    let (px, py) = (0.18 + j(0.03), -0.08 + j(0.03));
    b.object(&[(
        "bottle",
        [px - 0.04, py - 0.04, th],
        [px + 0.04, py + 0.04, th + 0.26],
    )]);
    b.object(&[("book", [0.05, 0.1, th], [0.27, 0.22, th + 0.05])]);
    let cx = tx + 0.3;
    b.object(&[
        ("chair", [cx - 0.2, -0.2, 0.4], [cx + 0.2, 0.2, 0.45]),
        ("chair", [cx + 0.16, -0.2, 0.45], [cx + 0.2, 0.2, 0.9]),
        ("chair", [cx - 0.2, -0.2, 0.0], [cx - 0.16, -0.16, 0.4]),
        ("chair", [cx + 0.16, 0.16, 0.0], [cx + 0.2, 0.2, 0.4]),
    ]);
    b.plant((-0.2 + j(0.05), -ty - 0.35), (0.12, 0.3), (0.22, 0.95));
    let pillars = ["door", "shelf", "cabinet", "picture", "sofa"];
    for i in 0..10 {
        let a = std::f64::consts::TAU * (i as f64 + 0.3 + j(0.2)) / 10.0;
        let d = 5.75 + j(1.25);
        let (x, y, w, h) = (d * a.cos(), d * a.sin(), 0.25 + j(0.08), 2.2 + j(0.8));
        b.object(&[(
            pillars[i % pillars.len()],
            [x - w, y - w, 0.0],
            [x + w, y + w, h],
        )]);
    }
    for i in 0..12 {
        let a = std::f64::consts::TAU * (i as f64 + 0.5 * j(1.0)) / 12.0;
        let (x, y) = (10.5 * a.cos(), 10.5 * a.sin());
        let (hw, h) = (1.2 + j(0.3), 3.0 + j(1.0));
        b.object(&[("picture", [x - hw, y - hw, 0.0], [x + hw, y + hw, h])]);
    }
    let r = OUTDOOR_BACKDROP;
    Room::from_parts([-r, -r, 0.0], [r, r, r], b)
}
