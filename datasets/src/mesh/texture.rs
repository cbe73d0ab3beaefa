//! Vertex colours of an OBJ mesh: the texel of the material's diffuse
//! texture under each vertex's UV, else the file's own vertex colours, and
//! a note for each reason a part of the mesh has neither.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use image::RgbImage;

use crate::error::DatasetError;

/// A material library (`mtllib`) that could not be loaded, and why.
#[derive(Debug, Clone)]
pub(super) struct MtlFailure {
    /// Its full path.
    pub path: PathBuf,
    /// What went wrong, as a phrase ("not found", "cannot be parsed (...)").
    pub reason: String,
}

/// The colour of texture coordinate `(u, v)`: the nearest texel, `v` up
/// (row 0 of the image is `v = 1`), coordinates outside `[0, 1]` wrapped
/// (repeat addressing, what renderers of these meshes use).
fn texel(image: &RgbImage, u: f64, v: f64) -> [u8; 3] {
    let wrap = |x: f64| {
        if (0.0..=1.0).contains(&x) {
            x
        } else {
            x.rem_euclid(1.0)
        }
    };
    let (w, h) = image.dimensions();
    // `as` saturates (NaN gives 0), and the clamps keep u = 1 and v = 0 on
    // the last column and row.
    let column = ((wrap(u) * w as f64).floor() as i64).clamp(0, w as i64 - 1);
    let row = (((1.0 - wrap(v)) * h as f64).floor() as i64).clamp(0, h as i64 - 1);
    image.get_pixel(column as u32, row as u32).0
}

/// A texture loaded once for every model using it, or why it could not be.
fn load_texture(path: &Path) -> Result<RgbImage, String> {
    match crate::imageio::open(path) {
        Ok(image) if image.width() > 0 && image.height() > 0 => Ok(image.to_rgb8()),
        Ok(_) => Err(format!("texture {} is empty", path.display())),
        Err(DatasetError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
            Err(format!("texture {} not found", path.display()))
        }
        Err(e) => Err(format!("texture {} cannot be read ({e})", path.display())),
    }
}

/// The file's own vertex colours of `mesh`, when every vertex has one:
/// channels in `[0, 1]`, or in `[0, 255]` where a file writes any above 1.
fn vertex_colours(mesh: &tobj::Mesh, scale: f64) -> Option<Vec<[u8; 3]>> {
    let c = &mesh.vertex_color;
    (!c.is_empty() && c.len() == mesh.positions.len()).then(|| {
        c.chunks_exact(3)
            .map(|rgb| [0, 1, 2].map(|k| (rgb[k] * scale).round().clamp(0.0, 255.0) as u8))
            .collect()
    })
}

/// Colours of the merged vertices of `models` (in their order), `None`
/// unless every model has some, and the notes saying why not or where the
/// colours came from instead (each once). `dir` is the OBJ's directory,
/// against which texture names are resolved.
pub(super) fn colour(
    obj: &Path,
    dir: &Path,
    models: &[tobj::Model],
    materials: &[tobj::Material],
    mtl_failures: &[MtlFailure],
) -> (Option<Vec<[u8; 3]>>, Vec<String>) {
    let high = models
        .iter()
        .flat_map(|m| &m.mesh.vertex_color)
        .any(|&c| c > 1.0);
    let scale = if high { 1.0 } else { 255.0 };
    let mut textures: HashMap<PathBuf, Result<RgbImage, String>> = HashMap::new();
    let mut problems: Vec<(String, bool)> = Vec::new();
    let mut colours = Some(Vec::new());
    for model in models {
        let mesh = &model.mesh;
        let vertices = mesh.positions.len() / 3;
        // A file with one material and no `usemtl` still means that one.
        let material = mesh
            .material_id
            .or((materials.len() == 1).then_some(0))
            .and_then(|i| materials.get(i));
        let texture = material
            .and_then(|m| m.diffuse_texture.as_deref())
            .filter(|t| !t.trim().is_empty());
        let mut problem = None;
        let mut from_texture = None;
        match texture {
            Some(name) => {
                let path = resolve(dir, name);
                let image = textures
                    .entry(path.clone())
                    .or_insert_with(|| load_texture(&path));
                match image {
                    Err(why) => problem = Some(why.clone()),
                    Ok(_) if mesh.texcoords.len() != 2 * vertices => {
                        problem = Some(format!(
                            "object '{}' has a texture but not every vertex has texture \
                             coordinates",
                            model.name
                        ));
                    }
                    Ok(image) => {
                        from_texture = Some(
                            mesh.texcoords
                                .chunks_exact(2)
                                .map(|uv| texel(image, uv[0], uv[1]))
                                .collect::<Vec<_>>(),
                        );
                    }
                }
            }
            None => {
                problem = Some(match mtl_failures.first() {
                    Some(f) => format!("material library {} {}", f.path.display(), f.reason),
                    None => "no texture (map_Kd) and no vertex colours".into(),
                });
            }
        }
        let model_colours = from_texture.or_else(|| vertex_colours(mesh, scale));
        if let Some(p) = problem {
            let fell_back = model_colours.is_some();
            // Vertex colours of a mesh without a material are no news.
            if !(fell_back && texture.is_none() && mtl_failures.is_empty()) {
                problems.push((p, fell_back));
            }
        }
        colours = match (colours, model_colours) {
            (Some(mut all), Some(c)) => {
                all.extend(c);
                Some(all)
            }
            _ => None,
        };
    }
    let mut notes: Vec<String> = Vec::new();
    for (problem, fell_back) in problems {
        let consequence = if colours.is_none() {
            "the point cloud has no colour"
        } else if fell_back {
            "using the OBJ's vertex colours"
        } else {
            continue;
        };
        let note = format!("{}: {problem}: {consequence}", obj.display());
        if !notes.contains(&note) {
            notes.push(note);
        }
    }
    (colours, notes)
}

/// The full path of a file named in an OBJ or MTL, relative to `dir`.
pub(super) fn resolve(dir: &Path, name: &str) -> PathBuf {
    dir.join(name.trim())
}

#[cfg(test)]
mod tests {
    use super::texel;
    use image::RgbImage;

    #[test]
    fn texel_wraps_clamps_and_flips_v() {
        // 2x2: row 0 (v near 1) red, green; row 1 blue, white.
        let image = RgbImage::from_fn(2, 2, |x, y| {
            image::Rgb(
                [[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255; 3]]][y as usize][x as usize],
            )
        });
        assert_eq!(texel(&image, 0.25, 0.75), [255, 0, 0]);
        assert_eq!(texel(&image, 0.75, 0.25), [255; 3]);
        // The edges u = 1 and v = 0 stay on the image.
        assert_eq!(texel(&image, 1.0, 0.0), [255; 3]);
        assert_eq!(texel(&image, 0.0, 1.0), [255, 0, 0]);
        // Outside [0, 1] repeats.
        assert_eq!(texel(&image, -0.25, 1.75), [0, 255, 0]);
        assert_eq!(texel(&image, 3.25, -2.75), [0, 0, 255]);
        // Not a number: some texel, no panic.
        texel(&image, f64::NAN, f64::INFINITY);
    }
}
