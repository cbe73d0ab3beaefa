//! Images meant for reading results: a colour bar with its scale for
//! relevancy images and animated GIFs of camera paths (a held-out render
//! next to its photograph: [`field_ops::strips`]).

use std::path::Path;

use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame, RgbaImage};

use field_ops::OpsError;
use field_ops::colormap::{to_u8, turbo};

/// 3x5 glyphs of the characters a scale label needs, one row per `u8`
/// (the low three bits, left to right).
fn glyph(c: char) -> [u8; 5] {
    match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        '-' => [0, 0, 7, 0, 0],
        _ => [0; 5],
    }
}

/// Draws `text` white on black into an RGB buffer of width `w` and height
/// `h`, top-left at `(x0, y0)`, at `scale` pixels per dot.
fn draw_text(buf: &mut [u8], w: usize, h: usize, x0: usize, y0: usize, text: &str, scale: usize) {
    for (i, c) in text.chars().enumerate() {
        let g = glyph(c);
        for (row, bits) in g.iter().enumerate() {
            for col in 0..3 {
                let on = (bits >> (2 - col)) & 1 == 1;
                for dy in 0..scale {
                    for dx in 0..scale {
                        let x = x0 + (4 * i + col) * scale + dx;
                        let y = y0 + row * scale + dy;
                        if x < w && y < h {
                            let v = if on { 255 } else { 0 };
                            buf[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&[v; 3]);
                        }
                    }
                }
            }
        }
    }
}

/// Appends a vertical colour bar to the right of an RGB image: Turbo from
/// relevancy 1 (top) down to the `threshold` cut, grey below it (pixels
/// there keep their rendered colour), labelled with the cosine similarity
/// at the top, at the cut and at the bottom (`lo`, `hi`: cosines at
/// relevancy 0 and 1). Returns the new width and pixels.
pub fn with_colour_bar(
    width: u32,
    height: u32,
    rgb: &[u8],
    threshold: f32,
    lo: f64,
    hi: f64,
) -> (u32, Vec<u8>) {
    let (w, h) = (width as usize, height as usize);
    let scale = if h >= 120 { 2 } else { 1 };
    let label_w = 4 * 5 * scale + 2;
    let bar_w = (w / 24).clamp(6, 24);
    let extra = 2 + bar_w + 2 + label_w;
    let nw = w + extra;
    let mut out = vec![0u8; 3 * nw * h];
    for y in 0..h {
        out[3 * y * nw..3 * (y * nw + w)].copy_from_slice(&rgb[3 * y * w..3 * (y + 1) * w]);
        let r = 1.0 - y as f32 / (h.max(2) - 1) as f32;
        let c = if r >= threshold {
            turbo(r).map(to_u8)
        } else {
            [96; 3]
        };
        for x in w + 2..w + 2 + bar_w {
            out[3 * (y * nw + x)..3 * (y * nw + x) + 3].copy_from_slice(&c);
        }
    }
    let cosine = |r: f64| lo + r * (hi - lo);
    let text_h = 5 * scale;
    let cut_y = ((1.0 - threshold) * (h.max(2) - 1) as f32) as usize;
    let x = w + 2 + bar_w + 2;
    for (y, value) in [
        (0, cosine(1.0)),
        (cut_y.saturating_sub(text_h / 2), cosine(threshold as f64)),
        (h.saturating_sub(text_h), cosine(0.0)),
    ] {
        draw_text(&mut out, nw, h, x, y, &format!("{value:.2}"), scale);
    }
    (nw as u32, out)
}

/// Writes RGB frames of one size as an endlessly looping animated GIF at
/// `fps` frames per second.
pub fn write_gif(
    path: &Path,
    width: u32,
    height: u32,
    frames: &[Vec<u8>],
    fps: u32,
) -> Result<(), OpsError> {
    let err = |m: String| OpsError::Image {
        path: path.to_path_buf(),
        message: m,
    };
    let file = std::fs::File::create(path).map_err(|e| OpsError::io(path, e))?;
    let mut enc = GifEncoder::new_with_speed(std::io::BufWriter::new(file), 10);
    enc.set_repeat(Repeat::Infinite)
        .map_err(|e| err(e.to_string()))?;
    let delay = Delay::from_numer_denom_ms(1000, fps.max(1));
    for rgb in frames {
        let rgba: Vec<u8> = rgb
            .chunks_exact(3)
            .flat_map(|p| [p[0], p[1], p[2], 255])
            .collect();
        let img = RgbaImage::from_raw(width, height, rgba)
            .ok_or_else(|| err(format!("a frame does not hold {width}x{height} pixels")))?;
        enc.encode_frame(Frame::from_parts(img, 0, 0, delay))
            .map_err(|e| err(e.to_string()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_bar_widens_the_image_and_greys_below_the_cut() {
        let (w, h) = (48u32, 40u32);
        let rgb = vec![10u8; (3 * w * h) as usize];
        let (nw, out) = with_colour_bar(w, h, &rgb, 0.5, -0.1, 0.3);
        assert!(nw > w);
        assert_eq!(out.len(), (3 * nw * h) as usize);
        let px = |x: u32, y: u32| {
            let i = 3 * (y * nw + x) as usize;
            [out[i], out[i + 1], out[i + 2]]
        };
        assert_eq!(px(0, 0), [10; 3]);
        assert_eq!(px(w + 3, 0), turbo(1.0).map(to_u8));
        assert_eq!(px(w + 3, h - 1), [96; 3]);
    }

    #[test]
    fn gif_has_every_frame() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.gif");
        let frames: Vec<Vec<u8>> = (0..3).map(|i| vec![40 * i as u8; 3 * 8 * 6]).collect();
        write_gif(&p, 8, 6, &frames, 10).unwrap();
        let decoder = image::codecs::gif::GifDecoder::new(std::io::BufReader::new(
            std::fs::File::open(&p).unwrap(),
        ))
        .unwrap();
        use image::AnimationDecoder;
        assert_eq!(decoder.into_frames().count(), 3);
        assert!(write_gif(&p, 8, 6, &[vec![0; 5]], 10).is_err());
    }
}
