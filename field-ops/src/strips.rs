//! Pictures that put a render beside what it should show: for a held-out
//! photograph, `photograph | render | absolute error | depth` at the
//! render's size (a strip), and all strips of a run stacked small (a
//! contact sheet).

use std::path::{Path, PathBuf};

use datasets::RgbImage;
use datasets::imageio::save_rgb8;
use image::imageops::FilterType;
use image::{ImageBuffer, Rgb, Rgb32FImage, RgbImage as Rgb8Image};

use crate::colormap::{to_u8, turbo};
use crate::error::OpsError;
use crate::render::RenderedView;

/// Mean absolute colour error mapped to the top of the error colour scale.
/// Fixed (not per image) so that error images of different views compare.
pub const ERROR_SCALE_MAX: f32 = 0.25;

/// How a photograph is brought to a render's size: the `image` crate's
/// triangle (bilinear) filter, widened to the scale when shrinking so that
/// every source pixel counts.
pub const PHOTOGRAPH_FILTER: &str = "triangle (bilinear, widened to the scale when shrinking)";

/// Height in pixels of a strip on the contact sheet.
pub const SHEET_ROW_HEIGHT: u32 = 120;

/// An RGB8 picture.
#[derive(Debug, Clone, PartialEq)]
pub struct Picture {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `height * width * 3` bytes, row-major.
    pub rgb: Vec<u8>,
}

impl Picture {
    /// Writes the picture as a PNG at `path`.
    pub fn save(&self, path: &Path) -> Result<(), OpsError> {
        Ok(save_rgb8(path, self.width, self.height, &self.rgb)?)
    }
}

/// The strips of a set of views, each written as it is made, and their
/// contact sheet at the end.
#[derive(Debug, Default)]
pub struct Strips {
    strips: Vec<Picture>,
}

impl Strips {
    /// Writes `{name}_strip.png` into `dir` ([`strip`] of `photo`, `view`
    /// and its coloured `depth`, all of the view's size) and keeps it for the
    /// sheet; `None` (nothing written) when the sizes differ.
    pub fn add(
        &mut self,
        photo: &RgbImage,
        view: &RenderedView,
        depth: &[u8],
        dir: &Path,
        name: &str,
    ) -> Result<Option<PathBuf>, OpsError> {
        let Some(s) = strip(photo, view, depth) else {
            return Ok(None);
        };
        let path = dir.join(format!("{name}_strip.png"));
        s.save(&path)?;
        self.strips.push(s);
        Ok(Some(path))
    }

    /// Writes the [`contact_sheet`] of the strips so far at `path`, rows of
    /// [`SHEET_ROW_HEIGHT`]; `None` (nothing written) without a strip.
    pub fn write_sheet(&self, path: &Path) -> Result<Option<PathBuf>, OpsError> {
        let Some(sheet) = contact_sheet(&self.strips, SHEET_ROW_HEIGHT) else {
            return Ok(None);
        };
        sheet.save(path)?;
        Ok(Some(path.to_path_buf()))
    }
}

/// `photo` at `width x height` ([`PHOTOGRAPH_FILTER`]); the photograph
/// itself when it already has that size.
pub fn resized_photograph(photo: &RgbImage, width: u32, height: u32) -> RgbImage {
    if (photo.width, photo.height) == (width, height) {
        return photo.clone();
    }
    let Some(img) = Rgb32FImage::from_raw(photo.width, photo.height, photo.to_f32().into_owned())
    else {
        return photo.clone();
    };
    let out = image::imageops::resize(&img, width, height, FilterType::Triangle);
    RgbImage::from_f32(width, height, out.into_raw())
}

/// `photo | render | error | depth` side by side (`4 * width` wide): the
/// error is the mean absolute difference over the three channels,
/// Turbo-coloured from 0 to [`ERROR_SCALE_MAX`]; `depth` is the view's
/// coloured depth (`3 * width * height` bytes). `None` when the sizes differ.
pub fn strip(photo: &RgbImage, view: &RenderedView, depth: &[u8]) -> Option<Picture> {
    let (w, h) = (view.width as usize, view.height as usize);
    if (photo.width, photo.height) != (view.width, view.height)
        || photo.len() != 3 * w * h
        || view.rgb.len() != 3 * w * h
        || depth.len() != 3 * w * h
    {
        return None;
    }
    let photo = photo.to_f32();
    let mut out = Vec::with_capacity(12 * w * h);
    for y in 0..h {
        let row = 3 * y * w..3 * (y + 1) * w;
        let (g, r) = (&photo[row.clone()], &view.rgb[row.clone()]);
        out.extend(g.iter().map(|&v| to_u8(v)));
        out.extend(r.iter().map(|&v| to_u8(v)));
        for x in 0..w {
            let e = (0..3)
                .map(|c| (g[3 * x + c] - r[3 * x + c]).abs())
                .sum::<f32>()
                / 3.0;
            out.extend(turbo(e / ERROR_SCALE_MAX).map(to_u8));
        }
        out.extend_from_slice(&depth[row]);
    }
    Some(Picture {
        width: 4 * view.width,
        height: view.height,
        rgb: out,
    })
}

/// `strips` stacked top to bottom, each scaled to `row_height` pixels high
/// ([`PHOTOGRAPH_FILTER`]), with a 2-pixel black gap between them; narrower
/// rows are padded black on the right. `None` without strips.
pub fn contact_sheet(strips: &[Picture], row_height: u32) -> Option<Picture> {
    let gap = 2u32;
    let rows: Vec<Rgb8Image> = strips
        .iter()
        .filter_map(|s| {
            let img: Rgb8Image = ImageBuffer::from_raw(s.width, s.height, s.rgb.clone())?;
            let w = ((s.width as f64 * row_height as f64 / s.height as f64).round() as u32).max(1);
            Some(image::imageops::resize(
                &img,
                w,
                row_height.max(1),
                FilterType::Triangle,
            ))
        })
        .collect();
    let width = rows.iter().map(|r| r.width()).max()?;
    let height = rows.iter().map(|r| r.height() + gap).sum::<u32>() - gap;
    let mut sheet = Rgb8Image::from_pixel(width, height, Rgb([0, 0, 0]));
    let mut y = 0;
    for r in &rows {
        image::imageops::replace(&mut sheet, r, 0, y as i64);
        y += r.height() + gap;
    }
    Some(Picture {
        width,
        height,
        rgb: sheet.into_raw(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(w: u32, h: u32, v: f32) -> RenderedView {
        RenderedView {
            width: w,
            height: h,
            rgb: vec![v; (3 * w * h) as usize],
            depth: vec![1.0; (w * h) as usize],
            acc: vec![1.0; (w * h) as usize],
            ..RenderedView::default()
        }
    }

    fn photo(w: u32, h: u32, v: f32) -> RgbImage {
        RgbImage {
            width: w,
            height: h,
            data: datasets::RgbData::F32(vec![v; (3 * w * h) as usize]),
        }
    }

    #[test]
    fn a_strip_puts_photograph_render_error_and_depth_side_by_side() {
        let depth = vec![7u8; 24];
        let s = strip(&photo(4, 2, 0.5), &view(4, 2, 0.5), &depth).unwrap();
        assert_eq!((s.width, s.height, s.rgb.len()), (16, 2, 96));
        let px = |x: usize| &s.rgb[3 * x..3 * x + 3];
        assert_eq!(px(0), [128; 3]);
        assert_eq!(px(4), [128; 3]);
        // Zero error: the error panel shows the bottom of the scale.
        assert_eq!(px(8), turbo(0.0).map(to_u8));
        assert_eq!(px(12), [7; 3]);
        let s = strip(&photo(4, 2, 0.5), &view(4, 2, 0.75), &depth).unwrap();
        assert_eq!(&s.rgb[24..27], &turbo(1.0).map(to_u8));
        assert!(strip(&photo(3, 2, 0.5), &view(4, 2, 0.5), &depth).is_none());
        assert!(strip(&photo(4, 2, 0.5), &view(4, 2, 0.5), &depth[3..]).is_none());
    }

    #[test]
    fn a_photograph_shrinks_to_the_render_size_keeping_its_mean() {
        // Columns alternating 0 and 1: halved, every pixel averages both.
        let (w, h) = (8u32, 4u32);
        let data = (0..w * h)
            .flat_map(|p| [(p % 2) as f32; 3])
            .collect::<Vec<f32>>();
        let p = RgbImage::from_f32(w, h, data);
        let small = resized_photograph(&p, 4, 2);
        assert_eq!((small.width, small.height, small.len()), (4, 2, 24));
        let small = small.to_f32();
        for v in small.iter() {
            assert!((v - 0.5).abs() < 0.2, "{v}");
        }
        let mean = small.iter().sum::<f32>() / 24.0;
        assert!((mean - 0.5).abs() < 0.05, "{mean}");
        assert_eq!(resized_photograph(&p, 8, 4), p);
    }

    #[test]
    fn strips_are_written_as_made_and_sheeted_at_the_end() {
        let dir = tempfile::tempdir().unwrap();
        let mut strips = Strips::default();
        let sheet = dir.path().join("sheet.png");
        assert_eq!(strips.write_sheet(&sheet).unwrap(), None);
        assert!(!sheet.exists());
        let depth = vec![7u8; 24];
        let a = strips
            .add(&photo(4, 2, 0.5), &view(4, 2, 0.5), &depth, dir.path(), "a")
            .unwrap();
        assert_eq!(a, Some(dir.path().join("a_strip.png")));
        let written = image::open(dir.path().join("a_strip.png")).unwrap();
        assert_eq!((written.width(), written.height()), (16, 2));
        // A photograph of another size makes no strip.
        let b = strips
            .add(&photo(3, 2, 0.5), &view(4, 2, 0.5), &depth, dir.path(), "b")
            .unwrap();
        assert_eq!(b, None);
        assert!(!dir.path().join("b_strip.png").exists());
        assert_eq!(strips.write_sheet(&sheet).unwrap(), Some(sheet.clone()));
        let s = image::open(&sheet).unwrap();
        // One strip, 16 x 2, at the sheet's row height.
        assert_eq!(
            (s.width(), s.height()),
            (8 * SHEET_ROW_HEIGHT, SHEET_ROW_HEIGHT)
        );
    }

    #[test]
    fn the_contact_sheet_stacks_every_strip_at_one_height() {
        let a = Picture {
            width: 40,
            height: 10,
            rgb: vec![200; 1200],
        };
        let b = Picture {
            width: 20,
            height: 10,
            rgb: vec![100; 600],
        };
        let sheet = contact_sheet(&[a, b], 5).unwrap();
        assert_eq!((sheet.width, sheet.height), (20, 12));
        assert_eq!(sheet.rgb.len(), 3 * 20 * 12);
        assert_eq!(sheet.rgb[0], 200);
        // The second row starts after the gap and is padded black on the right.
        let at = |x: u32, y: u32| sheet.rgb[(3 * (y * 20 + x)) as usize];
        assert_eq!(at(0, 5), 0);
        assert_eq!(at(0, 7), 100);
        assert_eq!(at(15, 7), 0);
        assert!(contact_sheet(&[], 5).is_none());
    }
}
