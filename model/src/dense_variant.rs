//! The training-free dense variants of a CLIP vision tower's last block, by
//! name: the `clip` crate runs them, and a scene's `scene.json` records
//! which one made its feature maps (so `datasets` names them too, and
//! cannot depend on `clip`).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// How the last block turns patch tokens into pixel-aligned features
/// (training-free; the other blocks run as trained). None of them keeps the
/// last block's residual connection or MLP.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DenseVariant {
    /// NACLIP (Hajimiri et al., 2025): key-key attention logits plus a 2D
    /// Gaussian window over the patch grid (std 5 patches), so that every
    /// patch attends to itself, its look-alikes and its neighbours.
    Naclip,
    /// ClearCLIP (Lan et al., 2024): query-query attention.
    Clearclip,
    /// MaskCLIP (Zhou et al., 2022): each token's value, through the output
    /// projection (no attention across tokens).
    Maskclip,
}

impl DenseVariant {
    /// Every variant, default first.
    pub const ALL: [Self; 3] = [Self::Naclip, Self::Clearclip, Self::Maskclip];

    /// The name used on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Naclip => "naclip",
            Self::Clearclip => "clearclip",
            Self::Maskclip => "maskclip",
        }
    }
}

impl fmt::Display for DenseVariant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for DenseVariant {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|v| v.name() == s)
            .ok_or_else(|| format!("unknown dense variant {s:?}: naclip, clearclip or maskclip"))
    }
}
