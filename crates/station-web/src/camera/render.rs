//! The simulated camera's picture: a machine's axes drawn as they are, one JPEG frame.
//!
//! Every axis is a track spanning its position limits with a carriage at its actual
//! position (green: enabled, grey: disabled, red: faulted; a white outline while it moves,
//! orange tick marks at the ends). A bar along the bottom advances with time, so a viewer
//! tells a live picture of a machine at rest from a frozen one.

use crate::backend::AxisView;

/// Frame width in pixels.
pub const WIDTH: u16 = 320;
/// Frame height in pixels.
pub const HEIGHT: u16 = 240;
/// JPEG quality (1-100).
const QUALITY: u8 = 70;

const BACKGROUND: [u8; 3] = [24, 28, 34];
const TRACK: [u8; 3] = [70, 78, 90];
const END_MARK: [u8; 3] = [230, 150, 40];
const ENABLED: [u8; 3] = [60, 190, 90];
const DISABLED: [u8; 3] = [140, 140, 140];
const FAULTED: [u8; 3] = [220, 60, 50];
const OUTLINE: [u8; 3] = [245, 245, 245];
const TICKER: [u8; 3] = [80, 140, 230];

/// An RGB picture being drawn.
struct Canvas {
    pixels: Vec<u8>,
}

impl Canvas {
    fn new() -> Self {
        let mut pixels = Vec::with_capacity(usize::from(WIDTH) * usize::from(HEIGHT) * 3);
        for _ in 0..usize::from(WIDTH) * usize::from(HEIGHT) {
            pixels.extend_from_slice(&BACKGROUND);
        }
        Canvas { pixels }
    }

    /// Fills the rectangle `[x0, x1) x [y0, y1)`, clipped to the frame.
    fn fill(&mut self, x0: i32, y0: i32, x1: i32, y1: i32, colour: [u8; 3]) {
        let (w, h) = (i32::from(WIDTH), i32::from(HEIGHT));
        for y in y0.clamp(0, h)..y1.clamp(0, h) {
            for x in x0.clamp(0, w)..x1.clamp(0, w) {
                // Both are inside the frame: the index is in the buffer.
                let i = usize::try_from((y * w + x) * 3).unwrap_or(0);
                if let Some(p) = self.pixels.get_mut(i..i + 3) {
                    p.copy_from_slice(&colour);
                }
            }
        }
    }

    /// A one-pixel rectangle outline.
    fn outline(&mut self, x0: i32, y0: i32, x1: i32, y1: i32, colour: [u8; 3]) {
        self.fill(x0, y0, x1, y0 + 1, colour);
        self.fill(x0, y1 - 1, x1, y1, colour);
        self.fill(x0, y0, x0 + 1, y1, colour);
        self.fill(x1 - 1, y0, x1, y1, colour);
    }
}

/// Where `position` lies between `min` and `max`, 0..=1 (0.5 when the range is empty or a
/// value is not finite: drawn in the middle rather than not at all).
fn fraction(position: f64, min: f64, max: f64) -> f64 {
    let span = max - min;
    if !(span.is_finite() && span > 0.0 && position.is_finite()) {
        return 0.5;
    }
    ((position - min) / span).clamp(0.0, 1.0)
}

/// Draws `axes` at `time_s` (seconds since the stream began) as one JPEG frame.
///
/// # Errors
/// The encoder's error (not expected for a frame of this fixed size).
pub fn frame(axes: &[AxisView], time_s: f64) -> Result<Vec<u8>, jpeg_encoder::EncodingError> {
    let mut c = Canvas::new();
    let (w, h) = (i32::from(WIDTH), i32::from(HEIGHT));
    let margin = 24;
    let rows = i32::try_from(axes.len().max(1)).unwrap_or(i32::MAX);
    let row_h = ((h - 40) / rows).max(6);
    for (k, axis) in axes.iter().enumerate() {
        let k = i32::try_from(k).unwrap_or(i32::MAX);
        let y = k.saturating_mul(row_h).saturating_add(12 + row_h / 2);
        if y > h {
            break; // more axes than rows: the rest are off the picture
        }
        c.fill(margin, y - 2, w - margin, y + 2, TRACK);
        c.fill(margin - 2, y - 8, margin, y + 8, END_MARK);
        c.fill(w - margin, y - 8, w - margin + 2, y + 8, END_MARK);
        let f = fraction(axis.position, axis.limits.min, axis.limits.max);
        // The fraction is within 0..=1: the carriage stays on the track.
        #[allow(clippy::cast_possible_truncation)]
        let x = margin + (f * f64::from(w - 2 * margin)).round() as i32;
        let half = (row_h / 3).clamp(3, 12);
        let colour = match (&axis.fault, axis.enabled) {
            (Some(_), _) => FAULTED,
            (None, true) => ENABLED,
            (None, false) => DISABLED,
        };
        c.fill(x - half, y - half, x + half, y + half, colour);
        if axis.moving {
            c.outline(x - half - 2, y - half - 2, x + half + 2, y + half + 2, OUTLINE);
        }
    }
    encode(c, time_s)
}

/// The picture shown while an external camera cannot be reached: a dark red frame crossed
/// out, with the live ticker.
///
/// # Errors
/// The encoder's error (not expected for a frame of this fixed size).
pub fn no_signal(time_s: f64) -> Result<Vec<u8>, jpeg_encoder::EncodingError> {
    let mut c = Canvas::new();
    let (w, h) = (i32::from(WIDTH), i32::from(HEIGHT));
    c.fill(0, 0, w, h, [70, 20, 20]);
    for k in 0..w {
        let y = k * h / w;
        c.fill(k, y - 2, k + 1, y + 2, FAULTED);
        c.fill(k, h - y - 2, k + 1, h - y + 2, FAULTED);
    }
    encode(c, time_s)
}

fn encode(mut c: Canvas, time_s: f64) -> Result<Vec<u8>, jpeg_encoder::EncodingError> {
    let (w, h) = (i32::from(WIDTH), i32::from(HEIGHT));
    // The live ticker: one sweep of the frame's width every 4 s.
    let sweep = if time_s.is_finite() { time_s.rem_euclid(4.0) / 4.0 } else { 0.0 };
    #[allow(clippy::cast_possible_truncation)]
    let tick = (sweep * f64::from(w)) as i32;
    c.fill(0, h - 6, tick, h - 2, TICKER);
    let mut jpeg = Vec::with_capacity(16 * 1024);
    jpeg_encoder::Encoder::new(&mut jpeg, QUALITY).encode(
        &c.pixels,
        WIDTH,
        HEIGHT,
        jpeg_encoder::ColorType::Rgb,
    )?;
    Ok(jpeg)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
mod tests {
    use super::*;
    use crate::backend::AxisLimits;

    fn axis(position: f64, moving: bool) -> AxisView {
        AxisView {
            id: "x".into(),
            name: "x".into(),
            device: "sim".into(),
            group: Some("cnc".into()),
            unit: "m".into(),
            position,
            velocity: 0.0,
            enabled: true,
            homed: true,
            moving,
            fault: None,
            limits: AxisLimits { min: 0.0, max: 1.0, max_speed: 1.0, max_acceleration: 1.0 },
            acceleration: 1.0,
            default_speed: 1.0,
        }
    }

    #[test]
    fn a_frame_is_a_jpeg_and_changes_with_the_axis() {
        let a = frame(&[axis(0.1, false)], 0.0).unwrap();
        let b = frame(&[axis(0.9, true)], 0.0).unwrap();
        assert_eq!(&a[..2], &[0xFF, 0xD8], "JPEG start of image");
        assert_eq!(&a[a.len() - 2..], &[0xFF, 0xD9], "JPEG end of image");
        assert_ne!(a, b);
    }

    #[test]
    fn odd_numbers_and_empty_machines_still_draw() {
        let mut nan = axis(f64::NAN, false);
        nan.limits.max = f64::INFINITY;
        assert!(frame(&[nan], f64::NAN).is_ok());
        assert!(frame(&[], 1.0).is_ok());
        let many: Vec<AxisView> = (0..40).map(|k| axis(f64::from(k) / 40.0, k % 2 == 0)).collect();
        assert!(frame(&many, 3.0).is_ok());
        assert!(no_signal(f64::INFINITY).is_ok());
    }
}
