//! The furnished room of a seed: its dimensions and, wall by wall, the
//! furniture and small objects placed in it, each jittered by the seed's
//! random stream in a fixed order (so a seed always gives the same room).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::room::{Builder, Room};

/// The room of a seed: dimensions and object placements jittered by the
/// seed, the same furniture and small objects in every room.
pub fn build_room(seed: u64) -> Room {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_f700);
    let mut j = |a: f64| rng.random_range(-a..a);
    let (hx, hy, h) = (3.0 + j(0.2), 2.5 + j(0.15), 2.7 + j(0.08));
    let mut b = Builder {
        primitives: Vec::new(),
        groups: Vec::new(),
    };
    dining_corner(&mut b, &mut j);
    sofa_wall(&mut b, &mut j, hy);
    let by0 = bed_wall(&mut b, &mut j, hx);
    north_wall(&mut b, &mut j, hy, h);
    west_wall(&mut b, &mut j, hx, hy, by0);
    // A potted plant in the south-east corner.
    b.plant((hx - 0.35, -hy + 0.35), (0.17, 0.35), (0.28, 1.2));
    Room::from_parts([-hx, -hy, 0.0], [hx, hy, h], b)
}

/// Rug and table near the middle, chairs at its ends, bowl / bottle / book on it.
fn dining_corner(b: &mut Builder, j: &mut impl FnMut(f64) -> f64) {
    let (cx, cy) = (-0.6 + j(0.15), 0.1 + j(0.15));
    b.object(&[(
        "rug",
        [cx - 1.2, cy - 0.8, 0.0],
        [cx + 1.2, cy + 0.8, 0.012],
    )]);
    let (tx, ty, th) = (0.6, 0.4, 0.74);
    let mut table = vec![(
        "table",
        [cx - tx, cy - ty, th - 0.04],
        [cx + tx, cy + ty, th],
    )];
    for (sx, sy) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
        let (lx, ly) = (cx + sx * (tx - 0.06), cy + sy * (ty - 0.06));
        table.push((
            "table",
            [lx - 0.03, ly - 0.03, 0.012],
            [lx + 0.03, ly + 0.03, th - 0.04],
        ));
    }
    b.object(&table);
    let (bx, by) = (cx + 0.25 + j(0.05), cy + 0.1 + j(0.05));
    b.object(&[(
        "bowl",
        [bx - 0.09, by - 0.09, th],
        [bx + 0.09, by + 0.09, th + 0.07],
    )]);
    let (ox, oy) = (cx - 0.3 + j(0.05), cy - 0.15 + j(0.05));
    b.object(&[(
        "bottle",
        [ox - 0.035, oy - 0.035, th],
        [ox + 0.035, oy + 0.035, th + 0.26],
    )]);
    b.object(&[(
        "book",
        [cx - 0.05, cy - 0.3, th],
        [cx + 0.17, cy - 0.14, th + 0.035],
    )]);
    for side in [-1.0, 1.0] {
        let sx = cx + side * (tx + 0.35);
        let (x0, x1) = (sx - 0.22, sx + 0.22);
        let mut chair = vec![("chair", [x0, cy - 0.22, 0.43], [x1, cy + 0.22, 0.47])];
        let back_x = if side > 0.0 { x1 - 0.04 } else { x0 };
        chair.push((
            "chair",
            [back_x, cy - 0.22, 0.47],
            [back_x + 0.04, cy + 0.22, 0.95],
        ));
        for (lx, ly) in [
            (x0, cy - 0.22),
            (x0, cy + 0.18),
            (x1 - 0.04, cy - 0.22),
            (x1 - 0.04, cy + 0.18),
        ] {
            chair.push(("chair", [lx, ly, 0.012], [lx + 0.04, ly + 0.04, 0.43]));
        }
        b.object(&chair);
    }
}

/// Sofa with two pillows against the south wall, a clock above it.
fn sofa_wall(b: &mut Builder, j: &mut impl FnMut(f64) -> f64, hy: f64) {
    let sx = -0.8 + j(0.2);
    let y0 = -hy + 0.02;
    b.object(&[
        ("sofa", [sx - 1.0, y0, 0.0], [sx + 1.0, y0 + 0.9, 0.42]),
        ("sofa", [sx - 1.0, y0, 0.42], [sx + 1.0, y0 + 0.2, 0.85]),
        (
            "sofa",
            [sx - 1.0, y0 + 0.2, 0.42],
            [sx - 0.8, y0 + 0.9, 0.62],
        ),
        (
            "sofa",
            [sx + 0.8, y0 + 0.2, 0.42],
            [sx + 1.0, y0 + 0.9, 0.62],
        ),
    ]);
    for px in [sx - 0.55, sx + 0.15] {
        b.object(&[("pillow", [px, y0 + 0.2, 0.42], [px + 0.4, y0 + 0.34, 0.78])]);
    }
    b.object(&[("clock", [sx - 0.15, -hy, 1.6], [sx + 0.15, -hy + 0.04, 1.9])]);
}

/// Bed against the east wall with a pillow and headboard; nightstand with
/// lamp and a picture. Returns where the bed starts along y.
fn bed_wall(b: &mut Builder, j: &mut impl FnMut(f64) -> f64, hx: f64) -> f64 {
    let by0 = -0.2 + j(0.1);
    b.object(&[
        ("bed", [hx - 2.0, by0, 0.0], [hx - 0.12, by0 + 1.5, 0.5]),
        ("bed", [hx - 0.12, by0, 0.0], [hx - 0.02, by0 + 1.5, 1.0]),
    ]);
    b.object(&[(
        "pillow",
        [hx - 0.55, by0 + 0.3, 0.5],
        [hx - 0.15, by0 + 1.2, 0.64],
    )]);
    let ny = by0 + 1.6;
    b.object(&[(
        "nightstand",
        [hx - 0.47, ny, 0.0],
        [hx - 0.02, ny + 0.42, 0.55],
    )]);
    let (lx, ly) = (hx - 0.25, ny + 0.21);
    b.object(&[
        (
            "lamp",
            [lx - 0.05, ly - 0.05, 0.55],
            [lx + 0.05, ly + 0.05, 0.85],
        ),
        (
            "lamp",
            [lx - 0.15, ly - 0.15, 0.85],
            [lx + 0.15, ly + 0.15, 1.1],
        ),
    ]);
    b.object(&[("picture", [hx - 0.03, by0 + 0.3, 1.3], [hx, by0 + 1.2, 1.9])]);
    by0
}

/// Cabinet and tv on the north wall, window with blinds, a vent.
fn north_wall(b: &mut Builder, j: &mut impl FnMut(f64) -> f64, hy: f64, h: f64) {
    let kx = -1.5 + j(0.2);
    b.object(&[(
        "cabinet",
        [kx - 0.5, hy - 0.45, 0.0],
        [kx + 0.5, hy - 0.01, 0.9],
    )]);
    b.object(&[(
        "tv-screen",
        [kx - 0.45, hy - 0.05, 1.15],
        [kx + 0.45, hy, 1.7],
    )]);
    let wx = 0.8 + j(0.2);
    b.object(&[("window", [wx - 0.6, hy - 0.02, 0.9], [wx + 0.6, hy, 2.1])]);
    b.object(&[(
        "blinds",
        [wx - 0.65, hy - 0.06, 1.75],
        [wx + 0.65, hy - 0.02, 2.2],
    )]);
    b.object(&[(
        "vent",
        [wx - 0.2, hy - 0.02, h - 0.3],
        [wx + 0.2, hy, h - 0.1],
    )]);
    b.object(&[("vent", [-0.2, -0.1, h - 0.02], [0.2, 0.1, h])]);
}

/// West wall: door with switch, shelf with books; wall plugs on every wall.
fn west_wall(b: &mut Builder, j: &mut impl FnMut(f64) -> f64, hx: f64, hy: f64, by0: f64) {
    let dy = 1.2 + j(0.1);
    b.object(&[("door", [-hx, dy - 0.45, 0.0], [-hx + 0.04, dy + 0.45, 2.05])]);
    b.object(&[(
        "switch",
        [-hx, dy - 0.65, 1.05],
        [-hx + 0.015, dy - 0.57, 1.17],
    )]);
    let (s0, s1) = (-1.6 + j(0.1), -0.6);
    for z in [1.2, 1.6] {
        b.object(&[("shelf", [-hx, s0, z], [-hx + 0.28, s1, z + 0.03])]);
        let mut y = s0 + 0.05;
        let mut books = Vec::new();
        while y < s1 - 0.35 {
            let t = 0.03 + rng_step(&mut y);
            books.push((
                "book",
                [-hx + 0.04, y, z + 0.03],
                [-hx + 0.24, y + t, z + 0.23 + t],
            ));
            y += t + 0.005;
        }
        b.object(&books);
    }
    for (p0, p1) in [
        ([-hx, -1.0, 0.27], [-hx + 0.015, -0.92, 0.33]),
        ([0.0, hy - 0.015, 0.27], [0.08, hy, 0.33]),
        ([hx - 0.015, by0 + 1.52, 0.6], [hx, by0 + 1.58, 0.68]),
        ([1.0, -hy, 0.27], [1.08, -hy + 0.015, 0.33]),
    ] {
        b.object(&[("wall-plug", p0, p1)]);
    }
}

/// Book thickness from the shelf position: a deterministic wobble, so books
/// differ without another random stream.
fn rng_step(y: &mut f64) -> f64 {
    0.02 * (0.5 + 0.5 * (*y * 37.0).sin())
}
