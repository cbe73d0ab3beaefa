//! The viewer's points for a scene without a cloud: back-projected from the
//! depth the field renders, they project back onto their pixels at that
//! depth; and the binary layout the page reads.

mod common;

use burn::nn::{Initializer, LinearConfig};
use burn::tensor::Device;
use datasets::synthetic::{SceneSize, generate};
use field_ops::render::{ViewSettings, render_view};
use viewer::points::{NO_CLASS, PointSource, encode, from_rendered_depth};

#[test]
fn points_from_rendered_depth_project_back_onto_their_pixels_at_that_depth() {
    let scene = generate(0, SceneSize::Ci).expect("CI scene");
    let device = Device::flex();
    let dim = scene.features.as_ref().expect("features").dim();
    let mut model = common::tiny_model(dim, &device);
    // A dense field: every ray stops in its first samples (opacity ~1).
    let mlp = model.mlp.as_mut().expect("the Mip-NeRF field");
    let [width, out] = mlp.density.weight.dims();
    mlp.density = LinearConfig::new(width, out)
        .with_initializer(Initializer::Constant { value: 5.0 })
        .init(&device);
    let camera = scene.frames[3].camera;
    let set = from_rendered_depth(
        &model,
        &[camera],
        &scene.scene_box,
        scene.background,
        (1, 32),
    );
    let small = camera.scaled(32, 18);
    let view = render_view(
        &model,
        &small,
        &scene.scene_box,
        &ViewSettings::new(scene.background, 4096),
    )
    .expect("never cancelled without an observer");
    let solid: Vec<usize> = (0..view.acc.len())
        .filter(|&i| view.acc[i] >= 0.5)
        .collect();
    assert_eq!(set.source, PointSource::RenderedDepth);
    assert!(
        solid.len() > 500,
        "the dense field fills the view: {}",
        solid.len()
    );
    assert_eq!(set.len(), solid.len());
    for (p, &i) in set.positions.iter().zip(&solid) {
        let (x, y) = ((i % 32) as f64, (i / 32) as f64);
        let q = small.project(*p).expect("in front of the camera");
        assert!(
            (q.u - x).abs() < 1e-3 && (q.v - y).abs() < 1e-3,
            "{q:?} vs ({x}, {y})"
        );
        assert!(
            (q.z - view.depth[i] as f64).abs() < 1e-3,
            "{} vs {}",
            q.z,
            view.depth[i]
        );
    }
    assert!(set.truth.iter().all(|&t| t == NO_CLASS));
    assert!(set.uncertainty.iter().all(|u| u.is_nan()));
}

#[test]
fn the_binary_layout_holds_every_array_where_the_page_reads_it() {
    let set = viewer::points::PointSet {
        positions: vec![[1.0, 2.0, 3.0], [-4.0, 5.5, 6.25], [0.0, 0.0, 1e3]],
        colours: vec![[1, 2, 3], [4, 5, 6], [7, 8, 9]],
        truth: vec![0, NO_CLASS, 2],
        uncertainty: vec![0.5, f32::NAN, 1.0],
        source: PointSource::Labelled,
    };
    let b = encode(&set, &[2, 1], 7);
    let n = 3;
    assert_eq!(b.len(), 16 + 24 * n);
    let f = |o: usize| f32::from_le_bytes(b[o..o + 4].try_into().expect("4"));
    let h = |o: usize| u16::from_le_bytes(b[o..o + 2].try_into().expect("2"));
    assert_eq!(&b[..4], b"ONPT");
    assert_eq!(u32::from_le_bytes(b[12..16].try_into().expect("4")), 7);
    assert_eq!(f(16 + 12 + 8), 6.25);
    assert_eq!(&b[16 + 12 * n + 4..16 + 12 * n + 8], &[4, 5, 6, 255]);
    // Predictions shorter than the cloud leave the rest without a class.
    assert_eq!(
        [h(16 + 16 * n), h(16 + 16 * n + 2), h(16 + 16 * n + 4)],
        [2, 1, NO_CLASS]
    );
    assert_eq!([h(16 + 18 * n), h(16 + 18 * n + 2)], [0, NO_CLASS]);
    assert!(f(16 + 20 * n + 4).is_nan());
    assert_eq!(f(16 + 20 * n + 8), 1.0);
}

#[test]
fn uncertainty_is_taken_from_the_nearest_csv_point_within_the_radius() {
    let dir = tempfile::tempdir().expect("temp dir");
    let csv = dir.path().join("uncertainty.csv");
    std::fs::write(
        &csv,
        "x,y,z,views,log_det,uncertainty,feature_error\n\
         0.0000,0.0000,0.0000,3,-1.0,0.25,\n\
         0.0500,0.0000,0.0000,2,-0.5,0.75,0.1\n\
         5.0000,5.0000,5.0000,1,0.0,1.00,\n",
    )
    .expect("csv");
    let mut set = viewer::points::PointSet {
        // Nearest to the first, nearest to the second, and far from all.
        positions: vec![[0.01, 0.0, 0.0], [0.04, 0.01, 0.0], [1.0, 1.0, 1.0]],
        colours: vec![[0; 3]; 3],
        truth: vec![NO_CLASS; 3],
        uncertainty: vec![f32::NAN; 3],
        source: PointSource::Labelled,
    };
    let matched = viewer::points::attach_uncertainty(&mut set, &csv, 0.1).expect("attach");
    assert_eq!(matched, 2);
    assert_eq!(set.uncertainty[..2], [0.25, 0.75]);
    assert!(set.uncertainty[2].is_nan(), "no CSV point within 0.1 m");
    std::fs::write(&csv, "x,y,z,views,log_det,uncertainty\n1,2,3,4,5\n").expect("csv");
    let e = viewer::points::attach_uncertainty(&mut set, &csv, 0.1)
        .expect_err("a short line")
        .to_string();
    assert!(e.contains("uncertainty.csv") && e.contains("line 2"), "{e}");
}
