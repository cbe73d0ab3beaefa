//! Confusion matrix, per-class IoU / accuracy and their means over the
//! head / common / tail class groups.
//!
//! Conventions:
//! - Points whose ground truth is [`IGNORE_LABEL`] (or out of range) are
//!   skipped entirely: they are neither true nor false for any class.
//! - `IoU_c = tp / (tp + fp + fn)`, `Acc_c = tp / (tp + fn)`.
//! - A class with no ground-truth points has no IoU or accuracy (`None`) and
//!   is **excluded from every mean** (mIoU and mAcc average only over classes
//!   present in the ground truth). Predictions of such a class are not lost:
//!   they are false negatives of the true class of those points.

use datasets::points::IGNORE_LABEL;
use field_ops::scores::{ClassScore, GroupScore, SegmentationScores};

/// Counts of (ground truth, prediction) pairs, row-major `[gt, pred]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfusionMatrix {
    /// Number of classes.
    pub classes: usize,
    /// `classes * classes` counts; row = ground truth, column = prediction.
    pub counts: Vec<u64>,
    /// Points per ground-truth class that received no prediction (a false
    /// negative of their class, a false positive of none).
    pub unpredicted: Vec<u64>,
}

/// Prediction value of a point that no method could label (for example a
/// point no view sees in pure projection mode).
pub const NO_PREDICTION: u32 = u32::MAX - 1;

impl ConfusionMatrix {
    /// An empty matrix over `classes` classes.
    pub fn new(classes: usize) -> Self {
        Self {
            classes,
            counts: vec![0; classes * classes],
            unpredicted: vec![0; classes],
        }
    }

    /// Adds one point; ignored or out-of-range labels are skipped, and
    /// [`NO_PREDICTION`] counts as a miss of the true class.
    pub fn add(&mut self, gt: u32, pred: u32) {
        let (g, p) = (gt as usize, pred as usize);
        if gt == IGNORE_LABEL || g >= self.classes {
            return;
        }
        if pred == NO_PREDICTION {
            self.unpredicted[g] += 1;
            return;
        }
        if p >= self.classes {
            return;
        }
        self.counts[g * self.classes + p] += 1;
    }

    /// Adds paired label slices (one scene; call again for further scenes).
    pub fn add_all(&mut self, gt: &[u32], pred: &[u32]) {
        for (&g, &p) in gt.iter().zip(pred) {
            self.add(g, p);
        }
    }

    /// Count of points with ground truth `gt` predicted as `pred`.
    pub fn get(&self, gt: usize, pred: usize) -> u64 {
        self.counts[gt * self.classes + pred]
    }

    /// Ground-truth points of class `c` (row sum).
    pub fn gt_count(&self, c: usize) -> u64 {
        (0..self.classes).map(|p| self.get(c, p)).sum::<u64>() + self.unpredicted[c]
    }

    /// Points predicted as class `c` (column sum).
    pub fn pred_count(&self, c: usize) -> u64 {
        (0..self.classes).map(|g| self.get(g, c)).sum()
    }

    /// IoU and accuracy of class `c`; `None` when it has no ground truth.
    pub fn class_scores(&self, c: usize) -> (Option<f64>, Option<f64>) {
        let tp = self.get(c, c);
        let gt = self.gt_count(c);
        if gt == 0 {
            return (None, None);
        }
        let fp = self.pred_count(c) - tp;
        let fneg = gt - tp;
        let iou = tp as f64 / (tp + fp + fneg) as f64;
        let acc = tp as f64 / gt as f64;
        (Some(iou), Some(acc))
    }
}

/// Class groups by frequency (indices into the class list).
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ClassSplit {
    /// Most frequent classes.
    pub head: Vec<String>,
    /// Middle classes.
    pub common: Vec<String>,
    /// Rarest classes.
    pub tail: Vec<String>,
}

/// Replica's head classes: of the 51 evaluation classes ordered by point
/// count, head = the first 17, common = the next 17, tail = the last 17.
pub const REPLICA_HEAD: [&str; 17] = [
    "wall",
    "ceiling",
    "floor",
    "chair",
    "blinds",
    "sofa",
    "table",
    "rug",
    "window",
    "lamp",
    "door",
    "pillow",
    "bench",
    "tv-screen",
    "cabinet",
    "pillar",
    "blanket",
];
/// Replica's common classes.
pub const REPLICA_COMMON: [&str; 17] = [
    "tv-stand",
    "cushion",
    "bin",
    "vent",
    "bed",
    "stool",
    "picture",
    "indoor-plant",
    "desk",
    "comforter",
    "nightstand",
    "shelf",
    "vase",
    "plant-stand",
    "basket",
    "plate",
    "monitor",
];
/// Replica's tail classes.
pub const REPLICA_TAIL: [&str; 17] = [
    "pipe",
    "panel",
    "desk-organizer",
    "wall-plug",
    "book",
    "box",
    "clock",
    "sculpture",
    "tissue-paper",
    "camera",
    "tablet",
    "pot",
    "bottle",
    "candle",
    "bowl",
    "cloth",
    "switch",
];

impl ClassSplit {
    /// Replica's 51-class head / common / tail split.
    pub fn replica() -> Self {
        let v = |a: &[&str]| a.iter().map(|s| s.to_string()).collect();
        Self {
            head: v(&REPLICA_HEAD),
            common: v(&REPLICA_COMMON),
            tail: v(&REPLICA_TAIL),
        }
    }

    /// Replica's split when every one of `names` is a Replica evaluation
    /// class (the synthetic scene uses a subset of them); `None` otherwise.
    pub fn replica_for(names: &[String]) -> Option<Self> {
        let s = Self::replica();
        let known = |n: &String| s.group_of(n).is_some();
        (!names.is_empty() && names.iter().all(known)).then_some(s)
    }

    /// `0` head, `1` common, `2` tail, `None` in no group.
    pub fn group_of(&self, name: &str) -> Option<usize> {
        [&self.head, &self.common, &self.tail]
            .iter()
            .position(|g| g.iter().any(|n| n == name))
    }
}

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

fn group_score<'a>(classes: impl Iterator<Item = &'a ClassScore>) -> GroupScore {
    let (mut ious, mut accs) = (Vec::new(), Vec::new());
    for c in classes {
        if let (Some(i), Some(a)) = (c.iou, c.acc) {
            ious.push(i);
            accs.push(a);
        }
    }
    GroupScore {
        miou: mean(&ious),
        macc: mean(&accs),
        classes: ious.len(),
    }
}

/// Scores of a confusion matrix whose classes are `names`, with group means
/// when `split` is given.
pub fn score(
    mode: &str,
    cm: &ConfusionMatrix,
    names: &[String],
    split: Option<&ClassSplit>,
) -> SegmentationScores {
    let per_class: Vec<ClassScore> = (0..cm.classes)
        .map(|c| {
            let (iou, acc) = cm.class_scores(c);
            ClassScore {
                name: names.get(c).cloned().unwrap_or_else(|| format!("class{c}")),
                iou,
                acc,
                points: cm.gt_count(c),
            }
        })
        .collect();
    let group = |g: usize| {
        split.map(|s| group_score(per_class.iter().filter(|c| s.group_of(&c.name) == Some(g))))
    };
    let points: u64 = cm.counts.iter().sum::<u64>() + cm.unpredicted.iter().sum::<u64>();
    let correct: u64 = (0..cm.classes).map(|c| cm.get(c, c)).sum();
    SegmentationScores {
        mode: mode.to_string(),
        all: group_score(per_class.iter()),
        head: group(0),
        common: group(1),
        tail: group(2),
        per_class,
        points,
        point_accuracy: if points == 0 {
            0.0
        } else {
            correct as f64 / points as f64
        },
    }
}

fn pct(v: Option<f64>) -> String {
    v.map_or_else(|| "    -".to_string(), |x| format!("{:5.1}", 100.0 * x))
}

/// A fixed-width table (percent) of mIoU / mAcc for all / head / common /
/// tail, one row per labelled result.
pub fn format_table(rows: &[(&str, &SegmentationScores)]) -> String {
    let mut s = format!(
        "{:<22} {:>5} {:>5} | {:>5} {:>5} | {:>5} {:>5} | {:>5} {:>5}\n",
        "method", "mIoU", "mAcc", "head", "", "comm", "", "tail", ""
    );
    s.push_str(&format!(
        "{:<22} {:>5} {:>5} | {:>5} {:>5} | {:>5} {:>5} | {:>5} {:>5}\n",
        "", "all", "all", "mIoU", "mAcc", "mIoU", "mAcc", "mIoU", "mAcc"
    ));
    for (label, r) in rows {
        let g = |x: Option<GroupScore>| (pct(x.and_then(|g| g.miou)), pct(x.and_then(|g| g.macc)));
        let (hi, ha) = g(r.head);
        let (ci, ca) = g(r.common);
        let (ti, ta) = g(r.tail);
        s.push_str(&format!(
            "{:<22} {} {} | {} {} | {} {} | {} {}\n",
            label,
            pct(r.all.miou),
            pct(r.all.macc),
            hi,
            ha,
            ci,
            ca,
            ti,
            ta
        ));
    }
    s
}

/// Per-class table: name, group, GT points, IoU and accuracy in percent.
pub fn format_per_class(r: &SegmentationScores, split: Option<&ClassSplit>) -> String {
    let mut s = format!(
        "{:<18} {:>6} {:>9} {:>6} {:>6}\n",
        "class", "group", "points", "IoU", "Acc"
    );
    for c in &r.per_class {
        let g = split
            .and_then(|sp| sp.group_of(&c.name))
            .map_or("-", |g| ["head", "common", "tail"][g]);
        s.push_str(&format!(
            "{:<18} {:>6} {:>9} {} {}\n",
            c.name,
            g,
            c.points,
            pct(c.iou),
            pct(c.acc)
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(n: &[&str]) -> Vec<String> {
        n.iter().map(|s| s.to_string()).collect()
    }

    /// Hand-computed case. Classes: 0 wall (head), 1 chair (head), 2 vase
    /// (common), 3 switch (tail, absent from the ground truth).
    ///
    /// Pairs (gt -> pred): wall: 4 -> wall, 1 -> chair; chair: 2 -> chair,
    /// 1 -> switch; vase: 1 -> vase, 1 -> wall; ignored: 3 points.
    ///
    /// wall:  tp 4, fp 1 (vase->wall), fn 1 -> IoU 4/6, Acc 4/5
    /// chair: tp 2, fp 1 (wall->chair), fn 1 -> IoU 2/4, Acc 2/3
    /// vase:  tp 1, fp 0, fn 1 -> IoU 1/2, Acc 1/2
    /// switch: no GT -> excluded from all means (its one false positive is
    /// already a false negative of chair).
    #[test]
    fn hand_computed_confusion() {
        let mut cm = ConfusionMatrix::new(4);
        let gt = [
            0,
            0,
            0,
            0,
            0,
            1,
            1,
            1,
            2,
            2,
            IGNORE_LABEL,
            IGNORE_LABEL,
            IGNORE_LABEL,
        ];
        let pred = [0, 0, 0, 0, 1, 1, 1, 3, 2, 0, 0, 3, 2];
        cm.add_all(&gt, &pred);
        let n = names(&["wall", "chair", "vase", "switch"]);
        let r = score("test", &cm, &n, ClassSplit::replica_for(&n).as_ref());
        let close = |a: Option<f64>, b: f64| (a.unwrap() - b).abs() < 1e-12;
        assert_eq!(r.points, 10);
        assert!((r.point_accuracy - 0.7).abs() < 1e-12);
        assert!(close(r.per_class[0].iou, 4.0 / 6.0));
        assert!(close(r.per_class[0].acc, 0.8));
        assert!(close(r.per_class[1].iou, 0.5));
        assert!(close(r.per_class[1].acc, 2.0 / 3.0));
        assert!(close(r.per_class[2].iou, 0.5));
        assert!(close(r.per_class[2].acc, 0.5));
        assert_eq!(r.per_class[3].iou, None);
        assert_eq!(r.per_class[3].points, 0);
        assert_eq!(r.all.classes, 3);
        assert!(close(r.all.miou, (4.0 / 6.0 + 0.5 + 0.5) / 3.0));
        assert!(close(r.all.macc, (0.8 + 2.0 / 3.0 + 0.5) / 3.0));
        let head = r.head.unwrap();
        assert!(close(head.miou, (4.0 / 6.0 + 0.5) / 2.0));
        assert!(close(r.common.unwrap().miou, 0.5));
        let tail = r.tail.unwrap();
        assert_eq!((tail.miou, tail.classes), (None, 0));
    }

    #[test]
    fn perfect_prediction_scores_one_and_table_prints() {
        let mut cm = ConfusionMatrix::new(3);
        cm.add_all(&[0, 1, 2, 2], &[0, 1, 2, 2]);
        let n = names(&["a", "b", "c"]);
        assert!(ClassSplit::replica_for(&n).is_none());
        let r = score("oracle", &cm, &n, None);
        assert_eq!(r.all.miou, Some(1.0));
        assert_eq!(r.all.macc, Some(1.0));
        assert!(r.head.is_none());
        let t = format_table(&[("oracle", &r)]);
        assert!(t.contains("100.0"), "{t}");
        let j = serde_json::to_value(&r).unwrap();
        assert_eq!(j["all"]["miou"], 1.0);
        assert!(j["head"].is_null());
    }

    #[test]
    fn out_of_range_labels_are_skipped() {
        let mut cm = ConfusionMatrix::new(2);
        cm.add(5, 0);
        cm.add(0, 9);
        cm.add(IGNORE_LABEL, 1);
        assert_eq!(cm.counts.iter().sum::<u64>(), 0);
        // A point without a prediction is a miss of its class only.
        cm.add(1, NO_PREDICTION);
        cm.add(1, 1);
        let (iou, acc) = cm.class_scores(1);
        assert_eq!((iou, acc), (Some(0.5), Some(0.5)));
        assert_eq!(cm.class_scores(0), (None, None));
    }

    #[test]
    fn replica_split_has_51_distinct_classes() {
        let s = ClassSplit::replica();
        let mut all: Vec<&String> = s.head.iter().chain(&s.common).chain(&s.tail).collect();
        all.sort();
        all.dedup();
        assert_eq!(all.len(), 51);
    }
}
