//! Writes Nice-SLAM Replica frames out as each phone export (3D Scanner
//! App, Polycam, Record3D EXR + JPG and R3D) and, for scoring
//! segmentation, labelled ground-truth points in Replica's world and in the
//! exports' ARKit world: the inputs of the phone-loader comparison in
//! `docs/guide/phone.md` (`scripts/phone-table.sh` runs it).

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use bench::phone_export::{self, ReplicaFrames, scanner};
use clap::Parser;

/// Replica frames as phone exports, and labelled points to score them by.
#[derive(Debug, Parser)]
#[command(name = "phone_exports")]
struct Args {
    /// The Nice-SLAM Replica directory (`results/`, `traj.txt`,
    /// `cam_params.json`).
    #[arg(long)]
    replica: PathBuf,
    /// Output directory (created; must not exist): `scanner-app/`,
    /// `polycam/`, `record3d/`, `capture.r3d`, `points_replica.ply`,
    /// `points_arkit.ply`.
    #[arg(long)]
    out: PathBuf,
    /// The classes of the labelled points with the colour each is taken
    /// for (`simulate_features --classes`' form: `wall=#d8cdc2,floor=#58595b`):
    /// each point gets the class of the nearest colour, its index in this
    /// list as its label.
    #[arg(long)]
    classes: String,
    /// Label every Nth depth pixel of every frame in each axis.
    #[arg(long, default_value_t = 16)]
    point_step: u32,
}

/// The colours of `NAME=#rrggbb,...`.
fn colours(spec: &str) -> Result<Vec<[f32; 3]>> {
    let mut out = Vec::new();
    for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (_, hex) = item
            .split_once('=')
            .with_context(|| format!("--classes: {item:?} is not NAME=#rrggbb"))?;
        let hex = hex.trim().trim_start_matches('#');
        if hex.len() != 6 || !hex.chars().all(|c| c.is_ascii_hexdigit()) {
            bail!("--classes: {item:?}: the colour is not #rrggbb");
        }
        let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).map(|v| v as f32 / 255.0);
        out.push([byte(0)?, byte(2)?, byte(4)?]);
    }
    if out.is_empty() {
        bail!("--classes lists no class");
    }
    Ok(out)
}

fn main() -> Result<()> {
    let args = Args::parse();
    if args.point_step == 0 {
        bail!("--point-step 0: must be at least 1");
    }
    let colours = colours(&args.classes)?;
    if args.out.exists() {
        bail!("{}: already exists", args.out.display());
    }
    let frames = ReplicaFrames::read(&args.replica)?;
    let out = &args.out;
    let what = scanner::ScannerExport {
        depth: true,
        mesh: true,
    };
    scanner::write(&frames, &out.join("scanner-app"), what)?;
    phone_export::polycam::write(&frames, &out.join("polycam"), true)?;
    phone_export::record3d::write_exr(&frames, &out.join("record3d"))?;
    phone_export::record3d::write_r3d(&frames, &out.join("capture.r3d"))?;
    let cloud = phone_export::labelled_points(&frames, &colours, args.point_step)?;
    datasets::points::write_ply(&out.join("points_replica.ply"), &cloud, &[])?;
    let arkit = phone_export::mapped(&cloud, &ReplicaFrames::to_arkit());
    datasets::points::write_ply(&out.join("points_arkit.ply"), &arkit, &[])?;
    println!(
        "{}: the exports of {} frames and {} labelled points",
        out.display(),
        frames.images.len(),
        cloud.positions.len()
    );
    Ok(())
}
