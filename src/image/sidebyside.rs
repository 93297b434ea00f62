//! `vdbphoton compare --side-by-side`: the image, the reference and their
//! difference next to each other in one PNG, with the figures written
//! under them, for putting a frame beside Cycles' at a glance.

use super::metrics::{diff_rgb8, Metrics};
use super::png_io::{preview_rgb8, write_png_rgb8};
use super::{ImageError, ImageRgb, View};
use std::path::Path;

/// A 5x7 pixel font (rows top down, bit 4 the leftmost column) for the
/// labels: digits, capitals and the punctuation the figures use.
const FONT: &[(char, [u8; 7])] = &[
    ('0', [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E]),
    ('1', [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E]),
    ('2', [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F]),
    ('3', [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E]),
    ('4', [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02]),
    ('5', [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E]),
    ('6', [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E]),
    ('7', [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08]),
    ('8', [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E]),
    ('9', [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C]),
    ('A', [0x0E, 0x11, 0x11, 0x11, 0x1F, 0x11, 0x11]),
    ('B', [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E]),
    ('C', [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E]),
    ('D', [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C]),
    ('E', [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F]),
    ('F', [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10]),
    ('G', [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F]),
    ('H', [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11]),
    ('I', [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E]),
    ('J', [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C]),
    ('K', [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11]),
    ('L', [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F]),
    ('M', [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11]),
    ('N', [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11]),
    ('O', [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E]),
    ('P', [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10]),
    ('Q', [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D]),
    ('R', [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11]),
    ('S', [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E]),
    ('T', [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04]),
    ('U', [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E]),
    ('V', [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04]),
    ('W', [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A]),
    ('X', [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11]),
    ('Y', [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04]),
    ('Z', [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F]),
    ('.', [0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C]),
    (',', [0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08]),
    (':', [0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00]),
    ('-', [0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00]),
    ('+', [0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00]),
    ('=', [0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00]),
    ('%', [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03]),
    ('(', [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02]),
    (')', [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08]),
    ('[', [0x0E, 0x08, 0x08, 0x08, 0x08, 0x08, 0x0E]),
    (']', [0x0E, 0x02, 0x02, 0x02, 0x02, 0x02, 0x0E]),
    ('/', [0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00]),
    ('_', [0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F]),
    ('\'', [0x0C, 0x04, 0x08, 0x00, 0x00, 0x00, 0x00]),
    ('<', [0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02]),
    ('>', [0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08]),
    ('!', [0x04, 0x04, 0x04, 0x04, 0x04, 0x00, 0x04]),
    ('?', [0x0E, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04]),
    ('#', [0x0A, 0x0A, 0x1F, 0x0A, 0x1F, 0x0A, 0x0A]),
    ('*', [0x00, 0x04, 0x15, 0x0E, 0x15, 0x04, 0x00]),
    (' ', [0x00; 7]),
];

/// An RGB canvas to draw pictures and text on.
struct Canvas {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
}

impl Canvas {
    fn new(width: usize, height: usize, fill: u8) -> Self {
        Self {
            width,
            height,
            rgb: vec![fill; width * height * 3],
        }
    }

    /// Copies a `w` x `h` picture (three bytes a pixel) to (`x`, `y`).
    fn blit(&mut self, x: usize, y: usize, w: usize, h: usize, rgb: &[u8]) {
        for row in 0..h {
            let dst = ((y + row) * self.width + x) * 3;
            self.rgb[dst..dst + w * 3].copy_from_slice(&rgb[row * w * 3..(row + 1) * w * 3]);
        }
    }

    /// Writes `text` (capitals; other letters are shown as capitals,
    /// unknown characters as '?') at (`x`, `y`), `scale` pixels a font
    /// pixel, clipped to the canvas.
    fn text(&mut self, x: usize, y: usize, scale: usize, text: &str) {
        for (i, ch) in text.chars().enumerate() {
            let c = ch.to_ascii_uppercase();
            let glyph = FONT
                .iter()
                .find(|g| g.0 == c)
                .or_else(|| FONT.iter().find(|g| g.0 == '?'))
                .map_or([0; 7], |g| g.1);
            let gx = x + i * 6 * scale;
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) == 0 {
                        continue;
                    }
                    for dy in 0..scale {
                        for dx in 0..scale {
                            let (px, py) = (gx + col * scale + dx, y + row * scale + dy);
                            if px < self.width && py < self.height {
                                let k = (py * self.width + px) * 3;
                                self.rgb[k..k + 3].copy_from_slice(&[235, 235, 235]);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Writes a PNG of `a` (labelled `a_name`), the reference `b` (`b_name`)
/// and their false-colour difference (red: `a` brighter, blue: darker; as
/// `compare --diff`), the figures of `m` written under them. Both pictures
/// are shown through `view` at `exposure_stops`. Written atomically.
#[allow(clippy::too_many_arguments)]
pub fn write_side_by_side(
    path: impl AsRef<Path>,
    a: &ImageRgb,
    b: &ImageRgb,
    a_name: &str,
    b_name: &str,
    m: &Metrics,
    exposure_stops: f32,
    view: View,
) -> Result<(), ImageError> {
    let (diff, scale) = diff_rgb8(a, b)?;
    let (w, h) = (a.width, a.height);
    let show = |img: &ImageRgb| preview_rgb8(img.pixels.iter().copied(), exposure_stops, view);
    let gap = 8;
    let text_scale = if w >= 240 { 2 } else { 1 };
    let line = 9 * text_scale;
    let width = 3 * w + 4 * gap;
    let height = h + 2 * gap + 3 * line + gap;
    let mut c = Canvas::new(width, height, 40);
    let labels = [
        a_name.to_string(),
        b_name.to_string(),
        format!("DIFFERENCE, FULL AT {scale:.1e}"),
    ];
    for (i, (pic, label)) in [show(a), show(b), diff].iter().zip(&labels).enumerate() {
        let x = gap + i * (w + gap);
        c.blit(x, gap, w, h, pic);
        // Cut long labels to the panel.
        let fits = (w / (6 * text_scale)).max(1);
        let label: String = label.chars().take(fits).collect();
        c.text(x, h + gap + gap / 2, text_scale, &label);
    }
    let y = h + gap + gap / 2 + line;
    c.text(
        gap,
        y,
        text_scale,
        &format!(
            "MEAN {:.5}  REFERENCE {:.5}  RATIO {:.4}",
            m.mean_a, m.mean_b, m.mean_ratio
        ),
    );
    c.text(
        gap,
        y + line,
        text_scale,
        &format!(
            "RMSE {:.3e}  RELMSE {:.3e}  PSNR {:.2} DB",
            m.rmse, m.rel_mse, m.psnr
        ),
    );
    write_png_rgb8(path.as_ref(), width, height, &c.rgb)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_draws_inside_the_canvas_only() {
        let mut c = Canvas::new(20, 9, 0);
        c.text(0, 0, 1, "a1%");
        c.text(15, 5, 2, "W");
        // Top row: 'A' (lower case drawn as capital) lights columns 1-3,
        // '1' column 8, '%' columns 12-13; the clipped 'W' starts lower.
        let first_row: Vec<usize> = (0..20).filter(|x| c.rgb[x * 3] > 0).collect();
        assert_eq!(first_row, vec![1, 2, 3, 8, 12, 13]);
        // 'W' at (15, 5), twice the size, is cut at the canvas' edges:
        // its top-left font pixel covers (15..17, 5..7).
        assert!(c.rgb[(5 * 20 + 15) * 3] > 0 && c.rgb[(6 * 20 + 16) * 3] > 0);
    }
}
