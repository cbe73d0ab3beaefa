//! The scores of a segmentation evaluation, as `eval segment` writes them
//! (`segmentation.json` of a run directory) and the sweep reads them.

/// Scores of one class.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClassScore {
    /// Class name.
    pub name: String,
    /// IoU in `[0, 1]`; `None` without ground-truth points.
    pub iou: Option<f64>,
    /// Accuracy (recall) in `[0, 1]`; `None` without ground-truth points.
    pub acc: Option<f64>,
    /// Ground-truth points of this class.
    pub points: u64,
}

/// Means over one group of classes.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GroupScore {
    /// Mean IoU over the group's classes with ground truth; `None` if none has.
    pub miou: Option<f64>,
    /// Mean accuracy over the same classes.
    pub macc: Option<f64>,
    /// Number of classes that entered the means.
    pub classes: usize,
}

/// The full result of one segmentation evaluation.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SegmentationScores {
    /// Mode that produced the predictions (`sampled`, `project`, ...).
    pub mode: String,
    /// Means over all classes with ground truth.
    pub all: GroupScore,
    /// Means over the head classes (`None` without a split).
    pub head: Option<GroupScore>,
    /// Means over the common classes.
    pub common: Option<GroupScore>,
    /// Means over the tail classes.
    pub tail: Option<GroupScore>,
    /// Scores of every class, in class-list order.
    pub per_class: Vec<ClassScore>,
    /// Points evaluated (ground truth not ignored).
    pub points: u64,
    /// Overall point accuracy (fraction of evaluated points correct).
    pub point_accuracy: f64,
}
