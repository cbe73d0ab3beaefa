//! Triangle meshes: OBJ reading (texture colours, notes, malformed files)
//! and the ray caster, checked against analytic geometry and against a
//! brute-force intersection written independently here (plane
//! intersection and a barycentric inside test, not Möller–Trumbore).

use std::path::{Path, PathBuf};

use datasets::mesh::{Raycaster, TriangleMesh, read_obj};
use model::geometry::{Camera, Distortion, Intrinsics, Pose, Vec3, look_at};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn add(a: Vec3, s: f64, b: Vec3) -> Vec3 {
    [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
}
fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

/// Nearest `t > 0` over all triangles: the plane's `t`, then the hit point
/// inside when its three sub-triangle areas (signed along the normal) are
/// all non-negative.
fn brute_force(mesh: &TriangleMesh, o: Vec3, d: Vec3) -> Option<(f64, usize)> {
    let mut best: Option<(f64, usize)> = None;
    for (k, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = tri.map(|i| mesh.positions[i as usize]);
        let n = cross(sub(b, a), sub(c, a));
        let denom = dot(n, d);
        if denom == 0.0 {
            continue;
        }
        let t = dot(n, sub(a, o)) / denom;
        if t <= 0.0 || best.is_some_and(|(bt, _)| bt <= t) {
            continue;
        }
        let p = add(o, t, d);
        let inside = [(a, b), (b, c), (c, a)]
            .iter()
            .all(|&(e0, e1)| dot(cross(sub(e1, e0), sub(p, e0)), n) >= -1e-12 * dot(n, n));
        if inside {
            best = Some((t, k));
        }
    }
    best
}

fn rel_close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs().max(1.0)
}

/// A closed axis-aligned box, two triangles a side, windings mixed.
fn box_mesh(lo: Vec3, hi: Vec3) -> TriangleMesh {
    let positions = (0..8)
        .map(|i| [0, 1, 2].map(|k| if i >> k & 1 == 1 { hi[k] } else { lo[k] }))
        .collect();
    let quads: [[u32; 4]; 6] = [
        [0, 1, 3, 2], // z = lo
        [4, 6, 7, 5], // z = hi
        [0, 4, 5, 1], // y = lo
        [2, 3, 7, 6], // y = hi
        [0, 2, 6, 4], // x = lo
        [1, 5, 7, 3], // x = hi
    ];
    let mut triangles = Vec::new();
    for (k, [a, b, c, d]) in quads.into_iter().enumerate() {
        if k % 2 == 0 {
            triangles.extend([[a, b, c], [a, c, d]]);
        } else {
            triangles.extend([[c, b, a], [a, d, c]]);
        }
    }
    TriangleMesh {
        positions,
        triangles,
        colors: None,
    }
}

fn intrinsics(width: u32, height: u32, f: f64) -> Intrinsics {
    Intrinsics {
        width,
        height,
        fx: f,
        fy: f * 1.07,
        cx: width as f64 * 0.47,
        cy: height as f64 * 0.53,
        distortion: Distortion::NONE,
    }
}

#[test]
fn box_room_depth_is_the_analytic_z_depth_of_the_walls() {
    let (lo, hi) = ([0.0, 0.0, 0.0], [4.0, 3.0, 2.5]);
    let mesh = box_mesh(lo, hi);
    assert_eq!(mesh.triangles.len(), 12);
    let caster = Raycaster::new(&mesh);
    let mut walls_seen = [false; 6];
    // Two views, wide (about 130 degrees across), that meet all six walls
    // between them; the second's pose given as a matrix.
    let second = look_at([3.2, 2.1, 0.6], [0.4, 0.9, 1.9], [-0.3, 0.1, 1.0]).expect("pose");
    for pose in [
        look_at([1.3, 1.1, 1.4], [3.1, 2.6, 0.7], [0.2, -0.3, 1.0]).expect("pose"),
        Pose::from_matrix(second.to_matrix()).expect("rigid"),
    ] {
        let camera = Camera {
            intrinsics: intrinsics(80, 60, 18.0),
            pose,
        };
        let depth = caster.depth_image(&camera);
        assert_eq!((depth.width, depth.height), (80, 60));
        for j in 0..60 {
            for i in 0..80 {
                let ray = camera.ray(i as f64, j as f64);
                let (o, d) = (ray.origin, ray.direction);
                // Leaving a box from inside: the nearest exit over the axes.
                let (mut want, mut wall) = (f64::INFINITY, 0);
                for k in 0..3 {
                    let bound = if d[k] > 0.0 { hi[k] } else { lo[k] };
                    let t = (bound - o[k]) / d[k];
                    if d[k] != 0.0 && t < want {
                        (want, wall) = (t, 2 * k + usize::from(d[k] > 0.0));
                    }
                }
                walls_seen[wall] = true;
                let got = caster.hit(o, d).expect("a ray from inside a box hits it");
                assert!(
                    rel_close(got, want, 1e-9),
                    "pixel ({i}, {j}): {got} vs {want}"
                );
                let z = depth.get(i, j);
                assert!(z > 0.0, "pixel ({i}, {j}) has no depth");
                assert_eq!(z, got as f32, "pixel ({i}, {j})");
                let hit = add(o, got, d);
                assert!(rel_close(pose.world_to_camera(hit)[2], want, 1e-9));
            }
        }
    }
    assert_eq!(walls_seen, [true; 6], "the view should meet every wall");
}

/// An icosahedron subdivided `levels` times, vertices on the sphere.
fn icosphere(centre: Vec3, r: f64, levels: usize) -> TriangleMesh {
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    #[rustfmt::skip]
    let mut v: Vec<Vec3> = vec![
        [-1.0, g, 0.0], [1.0, g, 0.0], [-1.0, -g, 0.0], [1.0, -g, 0.0],
        [0.0, -1.0, g], [0.0, 1.0, g], [0.0, -1.0, -g], [0.0, 1.0, -g],
        [g, 0.0, -1.0], [g, 0.0, 1.0], [-g, 0.0, -1.0], [-g, 0.0, 1.0],
    ];
    #[rustfmt::skip]
    let mut t: Vec<[u32; 3]> = vec![
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
        [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
        [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
        [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::new();
        for [a, b, c] in t {
            let mut m = |p: u32, q: u32| {
                *mid.entry((p.min(q), p.max(q))).or_insert_with(|| {
                    let (x, y) = (v[p as usize], v[q as usize]);
                    v.push([0, 1, 2].map(|k| (x[k] + y[k]) / 2.0));
                    v.len() as u32 - 1
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        t = next;
    }
    let positions = v.iter().map(|p| add(centre, r / norm(*p), *p)).collect();
    TriangleMesh {
        positions,
        triangles: t,
        colors: None,
    }
}

fn random_unit(rng: &mut ChaCha8Rng) -> Vec3 {
    loop {
        let p = [0; 3].map(|_| rng.random_range(-1.0..1.0));
        let n = norm(p);
        if n > 0.1 && n <= 1.0 {
            return p.map(|x| x / n);
        }
    }
}

#[test]
fn sphere_hits_lie_between_the_inscribed_and_circumscribed_radii() {
    let (c, r) = ([0.3, -0.7, 2.1], 1.5);
    let mesh = icosphere(c, r, 4);
    assert_eq!(mesh.triangles.len(), 20 * 4usize.pow(4));
    // Every face is outside this sphere and inside the circumscribed one.
    let inscribed = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, cc] = t.map(|i| mesh.positions[i as usize]);
            let n = cross(sub(b, a), sub(cc, a));
            dot(n, sub(a, c)).abs() / norm(n)
        })
        .fold(f64::INFINITY, f64::min);
    assert!(inscribed > 0.99 * r && inscribed < r);
    let caster = Raycaster::new(&mesh);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (mut hits, mut misses) = (0, 0);
    for _ in 0..3000 {
        let o = add(c, rng.random_range(3.0..6.0), random_unit(&mut rng));
        let aim = add(c, rng.random_range(0.0..2.2 * r), random_unit(&mut rng));
        let scale = rng.random_range(0.2..5.0);
        let d = sub(aim, o).map(|x| x * scale);
        // Closest approach of the line to the centre.
        let s = dot(sub(c, o), d) / dot(d, d);
        let closest = norm(sub(add(o, s, d), c));
        match caster.hit(o, d) {
            Some(t) => {
                hits += 1;
                let dist = norm(sub(add(o, t, d), c));
                assert!(dist >= inscribed * (1.0 - 1e-12) && dist <= r * (1.0 + 1e-12));
                assert!(closest <= r, "a hit from a ray missing the bounding sphere");
            }
            None => {
                misses += 1;
                assert!(closest > inscribed, "a miss through the inscribed sphere");
            }
        }
    }
    assert!(hits > 500 && misses > 500, "{hits} hits, {misses} misses");
    // Rays through the centre stop at the face they meet: |o - c| minus
    // the distance from the centre to the hit point on that face.
    for _ in 0..500 {
        let o = add(c, rng.random_range(2.0..6.0), random_unit(&mut rng));
        let scale = rng.random_range(0.1..3.0);
        let d = sub(c, o).map(|x| x * scale);
        let t = caster.hit(o, d).expect("a ray through the centre hits");
        let (want, face) = brute_force(&mesh, o, d).expect("brute force hits");
        assert!(rel_close(t, want, 1e-12), "{t} vs {want}");
        let [a, b, cc] = mesh.triangles[face].map(|i| mesh.positions[i as usize]);
        let n = cross(sub(b, a), sub(cc, a));
        let on_face = dot(n, sub(add(o, t, d), a)).abs() / norm(n);
        assert!(on_face < 1e-12, "the hit is {on_face} off the face's plane");
        let to_face = norm(sub(add(o, want, d), c));
        assert!(rel_close(t * norm(d), norm(sub(o, c)) - to_face, 1e-12));
    }
}

#[test]
fn bvh_nearest_hit_equals_brute_force_on_random_triangles() {
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let mut mesh = TriangleMesh::default();
    for k in 0..2000u32 {
        let centre = [0; 3].map(|_| rng.random_range(-5.0..5.0));
        let size = rng.random_range(0.05..1.5);
        for _ in 0..3 {
            let p = random_unit(&mut rng);
            mesh.positions
                .push(add(centre, size * rng.random_range(0.2..1.0), p));
        }
        mesh.triangles.push([3 * k, 3 * k + 1, 3 * k + 2]);
    }
    let caster = Raycaster::new(&mesh);
    let mut hits = 0;
    for i in 0..5000 {
        let o = [0; 3].map(|_| rng.random_range(-8.0..8.0));
        // Half the rays aim at a triangle, so that many hit.
        let d = if i % 2 == 0 {
            let t = mesh.triangles[rng.random_range(0..2000)];
            let w = [0; 3].map(|_| rng.random_range(0.05..1.0));
            let sum = w[0] + w[1] + w[2];
            let mut target = [0.0; 3];
            for (k, &v) in t.iter().enumerate() {
                target = add(target, w[k] / sum, mesh.positions[v as usize]);
            }
            let scale = rng.random_range(0.3..3.0);
            sub(target, o).map(|x| x * scale)
        } else {
            let scale = rng.random_range(0.1..10.0);
            random_unit(&mut rng).map(|x| x * scale)
        };
        let got = caster.hit(o, d);
        let want = brute_force(&mesh, o, d).map(|(t, _)| t);
        match (got, want) {
            (Some(g), Some(w)) => {
                hits += 1;
                assert!(rel_close(g, w, 1e-12), "ray {i}: {g} vs {w}");
            }
            (None, None) => {}
            _ => panic!("ray {i}: BVH {got:?}, brute force {want:?}"),
        }
    }
    assert!(hits > 1500, "only {hits} hits");
}

/// Colour of square `(col, row)` of the 8x8 board (row 0 at the image's
/// top): black and white, with three coloured squares that a swapped
/// channel or an unflipped `v` would misplace.
fn square_colour(col: u32, row: u32) -> [u8; 3] {
    match (col, row) {
        (0, 0) => [255, 0, 0],
        (5, 2) => [0, 0, 255],
        (7, 7) => [0, 255, 0],
        _ if (col + row).is_multiple_of(2) => [255, 255, 255],
        _ => [0, 0, 0],
    }
}

/// A grid of 8x8 vertices, vertex `(i, j)` at `(i, j, 0)` with the UV of
/// the centre of board square `(i, 7 - j)` (v up), as 7x7 quads in one
/// object; a second object, a triangle at `z = 1` with UVs outside
/// `[0, 1]`; `checker.mtl` naming `checker.png` (written when `png`).
fn write_checker(dir: &Path, png: bool) -> PathBuf {
    let mut obj = String::from("# grid\nmtllib checker.mtl\no grid\nusemtl board\n");
    for j in 0..8 {
        for i in 0..8 {
            obj += &format!(
                "v {i} {j} 0\nvt {} {}\n",
                (i as f64 + 0.5) / 8.0,
                (j as f64 + 0.5) / 8.0
            );
        }
    }
    for j in 0..7 {
        for i in 0..7 {
            let v = |di: usize, dj: usize| 8 * (j + dj) + i + di + 1;
            let (a, b, c, d) = (v(0, 0), v(1, 0), v(1, 1), v(0, 1));
            obj += &format!("f {a}/{a} {b}/{b} {c}/{c} {d}/{d}\n");
        }
    }
    // Wrapped: (1.0625, -0.0625) is (0.0625, 0.9375), the red square;
    // (-0.9375, 2.0625) is (0.0625, 0.0625), square (0, 7); (2.5625, 0.5625)
    // is square (4, 3).
    obj += "o wrapped\nusemtl board\nv 10 0 1\nv 11 0 1\nv 10 1 1\n";
    obj += "vt 1.0625 -0.0625\nvt -0.9375 2.0625\nvt 2.5625 0.5625\nf -3/-3 -2/-2 -1/-1\n";
    std::fs::write(dir.join("grid.obj"), obj).expect("write obj");
    std::fs::write(
        dir.join("checker.mtl"),
        "newmtl board\nKd 1 1 1\nmap_Kd checker.png\n",
    )
    .expect("write mtl");
    if png {
        let image =
            image::RgbImage::from_fn(32, 32, |x, y| image::Rgb(square_colour(x / 4, y / 4)));
        image.save(dir.join("checker.png")).expect("write png");
    }
    dir.join("grid.obj")
}

#[test]
fn checkerboard_texture_colours_each_vertex_with_its_square() {
    let dir = tempfile::tempdir().expect("tmp");
    let path = write_checker(dir.path(), true);
    let file = read_obj(&path).expect("read");
    assert!(file.notes.is_empty(), "{:?}", file.notes);
    let mesh = &file.mesh;
    assert_eq!(mesh.positions.len(), 64 + 3);
    assert_eq!(mesh.triangles.len(), 2 * 49 + 1);
    let colours = mesh.colors.as_ref().expect("colours");
    let mut checked = 0;
    for (p, colour) in mesh.positions.iter().zip(colours) {
        let want = match *p {
            [10.0, 0.0, 1.0] => [255, 0, 0],
            [11.0, 0.0, 1.0] => square_colour(0, 7),
            [10.0, 1.0, 1.0] => square_colour(4, 3),
            [x, y, 0.0] => square_colour(x as u32, 7 - y as u32),
            _ => panic!("unexpected vertex {p:?}"),
        };
        assert_eq!(*colour, want, "vertex at {p:?}");
        checked += 1;
    }
    assert_eq!(checked, 67);
    // The red square is the vertex with UV (0.0625, 0.9375): top left.
    let red = mesh
        .positions
        .iter()
        .position(|p| *p == [0.0, 7.0, 0.0])
        .expect("vertex");
    assert_eq!(colours[red], [255, 0, 0]);
    let cloud = mesh.point_cloud();
    assert_eq!(cloud.positions, mesh.positions);
    assert_eq!(cloud.colors, mesh.colors);
    assert_eq!(cloud.labels, None);
}

#[test]
fn missing_texture_loads_without_colour_and_says_so_once() {
    let dir = tempfile::tempdir().expect("tmp");
    let path = write_checker(dir.path(), false);
    let file = read_obj(&path).expect("read without texture");
    assert_eq!(file.mesh.triangles.len(), 99);
    assert_eq!(file.mesh.colors, None);
    assert_eq!(file.notes.len(), 1, "{:?}", file.notes);
    let note = &file.notes[0];
    for word in ["grid.obj", "checker.png", "not found", "no colour"] {
        assert!(note.contains(word), "note {note:?} lacks {word:?}");
    }
    assert_eq!(file.mesh.point_cloud().colors, None);
    // Without the material library, the note names the library instead.
    std::fs::remove_file(dir.path().join("checker.mtl")).expect("rm");
    let file = read_obj(&path).expect("read without mtl");
    assert_eq!(file.mesh.colors, None);
    assert_eq!(file.notes.len(), 1, "{:?}", file.notes);
    assert!(file.notes[0].contains("checker.mtl"), "{:?}", file.notes);
}

#[test]
fn vertex_colours_are_used_without_a_texture() {
    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("c.obj");
    std::fs::write(
        &path,
        "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 0.5\nf 1 2 3\n",
    )
    .expect("write");
    let file = read_obj(&path).expect("read");
    assert!(file.notes.is_empty(), "{:?}", file.notes);
    let mesh = &file.mesh;
    let colours = mesh.colors.as_ref().expect("colours");
    for (p, c) in mesh.positions.iter().zip(colours) {
        let want = match *p {
            [0.0, 0.0, 0.0] => [255, 0, 0],
            [1.0, 0.0, 0.0] => [0, 255, 0],
            _ => [0, 0, 128],
        };
        assert_eq!(*c, want, "vertex {p:?}");
    }
}

fn assert_err(path: &Path, words: &[&str]) {
    let msg = read_obj(path).expect_err("an error").to_string();
    assert!(
        msg.contains(&path.display().to_string()),
        "{msg:?} does not name the file"
    );
    for w in words {
        assert!(msg.contains(w), "{msg:?} does not mention {w:?}");
    }
}

#[test]
fn malformed_objs_are_errors_naming_the_file_and_the_problem() {
    let dir = tempfile::tempdir().expect("tmp");
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).expect("write");
        p
    };
    let mut forty = String::new();
    for k in 0..40 {
        forty += &format!("v {k} {} 0\n", k % 3);
    }
    let mut past = forty.clone();
    for k in 0..11 {
        past += &format!("f {} {} {}\n", k + 1, k + 2, k + 3);
    }
    past += "f 1 2 57\n";
    assert_err(
        &write("past.obj", &past),
        &["face 12", "vertex 57", "40 vertices"],
    );
    let relative = format!("{forty}f -1 -2 -41\n");
    assert_err(
        &write("relative.obj", &relative),
        &["face 1", "vertex -41", "40 vertices"],
    );
    let zero = format!("{forty}f 0 1 2\n");
    assert_err(
        &write("zero.obj", &zero),
        &["face 1", "vertex 0", "start at 1"],
    );
    let uv = format!("{forty}vt 0 0\nf 1/1 2/2 3/1\n");
    assert_err(
        &write("uv.obj", &uv),
        &["face 1", "texture coordinate 2", "has 1 texture coordinate"],
    );
    assert_err(&write("empty.obj", ""), &["no faces"]);
    assert_err(&write("points.obj", &forty), &["no faces", "40 vertices"]);
    let nan = "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n";
    assert_err(
        &write("nan.obj", nan),
        &["line 3", "vertex 3", "non-finite"],
    );
    let inf = "v 0 0 0\nv 1 0 0\nv 0 1 inf\nf 1 2 3\n";
    assert_err(&write("inf.obj", inf), &["non-finite"]);
    assert_err(
        &write("word.obj", "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n"),
        &["line 2", "vertex"],
    );
    assert_err(
        &write("face.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 b 3\n"),
        &["face 1", "line 4", "'b'"],
    );
    assert_err(&write("binary.obj", "v 0 0 0\n\u{0}\u{ff}\n"), &[]);
    std::fs::write(
        dir.path().join("latin1.obj"),
        b"v 0 0 0\n# caf\xe9\nf 1 1 1\n",
    )
    .expect("write");
    assert_err(&dir.path().join("latin1.obj"), &[]);
    assert_err(&dir.path().join("absent.obj"), &[]);
}

#[test]
fn depth_image_is_the_hit_along_each_camera_ray() {
    let (c, r) = ([0.0, 0.0, 0.0], 1.0);
    let mesh = icosphere(c, r, 3);
    let caster = Raycaster::new(&mesh);
    let mut intr = intrinsics(48, 36, 30.0);
    intr.distortion = Distortion {
        k1: -0.05,
        p1: 0.001,
        ..Distortion::NONE
    };
    let camera = Camera {
        intrinsics: intr,
        pose: look_at([2.2, -1.4, 0.9], [0.2, 0.1, -0.1], [0.0, 0.0, 1.0]).expect("pose"),
    };
    let depth = caster.depth_image(&camera);
    let (mut hits, mut misses) = (0, 0);
    for j in 0..36 {
        for i in 0..48 {
            let ray = camera.ray(i as f64, j as f64);
            let want = caster
                .hit(ray.origin, ray.direction)
                .map_or(0.0, |t| t as f32);
            assert_eq!(depth.get(i, j), want, "pixel ({i}, {j})");
            if want > 0.0 { hits += 1 } else { misses += 1 }
        }
    }
    assert!(hits > 200 && misses > 200, "{hits} hits, {misses} misses");
}

#[test]
fn a_fronto_parallel_wall_has_one_z_depth_across_the_image() {
    let distance = 3.7;
    // An arbitrary rotation (from a look-at with a tilted up vector), as a
    // matrix, and a wall facing the camera `distance` ahead.
    let m = look_at([0.4, 1.0, -0.3], [1.9, -0.2, 0.8], [0.3, 0.5, 1.0])
        .expect("pose")
        .to_matrix();
    let pose = Pose::from_matrix(m).expect("rigid");
    let (x, y, f) = (
        [0, 1, 2].map(|k| m[k][0]),
        [0, 1, 2].map(|k| m[k][1]),
        pose.forward(),
    );
    let centre = add(pose.center(), distance, f);
    let corner = |sx: f64, sy: f64| add(add(centre, 20.0 * sx, x), 20.0 * sy, y);
    let mesh = TriangleMesh {
        positions: vec![
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        colors: None,
    };
    let caster = Raycaster::new(&mesh);
    let camera = Camera {
        intrinsics: intrinsics(40, 30, 25.0),
        pose,
    };
    let depth = caster.depth_image(&camera);
    for j in 0..30 {
        for i in 0..40 {
            let z = depth.get(i, j);
            assert!(
                (z as f64 - distance).abs() < 1e-6 * distance,
                "pixel ({i}, {j}): {z}"
            );
            let ray = camera.ray(i as f64, j as f64);
            let t = caster.hit(ray.origin, ray.direction).expect("hit");
            assert!(rel_close(t, distance, 1e-12), "pixel ({i}, {j}): {t}");
        }
    }
    // The corner pixel's ray is much longer than the z-depth: the image is
    // z, not distance along the ray.
    let ray = camera.ray(0.0, 0.0);
    let t = caster.hit(ray.origin, ray.direction).expect("hit");
    assert!(t * norm(ray.direction) > 1.3 * distance);
    // Behind the camera and parallel to the wall, nothing.
    assert_eq!(caster.hit(pose.center(), f.map(|v| -v)), None);
    assert_eq!(caster.hit(pose.center(), x), None);
    assert_eq!(caster.hit(pose.center(), [0.0; 3]), None);
    assert_eq!(caster.hit([f64::NAN, 0.0, 0.0], f), None);
    // An empty mesh hits nothing and builds.
    assert_eq!(
        Raycaster::new(&TriangleMesh::default()).hit([0.0; 3], [1.0, 0.0, 0.0]),
        None
    );
}
