use datasets::synthetic::{SceneSize, generate};
use eval::metrics::{ConfusionMatrix, score};
use eval::similarity::ClassScorer;
#[test]
fn diag() {
    let scene = generate(7, SceneSize::Ci).unwrap();
    let cl = scene.classes.as_ref().unwrap();
    let f = scene.features.as_ref().unwrap();
    let scorer = ClassScorer::new(&cl.data, cl.dim, f.pca.as_ref()).unwrap();
    let mut cm = ConfusionMatrix::new(cl.names.len());
    for (fr, m) in scene.frames.iter().zip(&f.maps) {
        let k = fr.camera.intrinsics;
        let pl = fr.labels.as_ref().unwrap();
        for y in 0..k.height { for x in 0..k.width {
            let v: Vec<f32> = m.lookup(x as f64, y as f64, k.width, k.height).iter().map(|h| h.to_f32()).collect();
            let l = pl[(y * k.width + x) as usize];
            cm.add(if l == u16::MAX { u32::MAX } else { l as u32 }, scorer.argmax(&v));
        }}
    }
    let r = score("2d pixels", &cm, &cl.names, None);
    println!("map {}x{} dim {}; pixel mIoU {:?} mAcc {:?} acc {}", f.maps[0].width, f.maps[0].height, f.maps[0].dim, r.all.miou, r.all.macc, r.point_accuracy);
    for c in &r.per_class { println!("{} {:?} {:?} {}", c.name, c.iou, c.acc, c.points); }
}
