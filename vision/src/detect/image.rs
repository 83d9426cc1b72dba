//! Grey-level images for the detectors: loading, conversion to floating point, smoothing.

use std::path::Path;

use image::GrayImage;
use rayon::prelude::*;

use crate::error::{Result, VisionError};

/// A single-channel floating-point image, row-major, values in digital numbers (0..255 for
/// 8-bit sources). Pixel `(x, y)` is centred on `(x, y)`.
#[derive(Clone, Debug, PartialEq)]
pub struct GrayF32 {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width * height` values, row by row.
    pub data: Vec<f32>,
}

impl GrayF32 {
    /// Converts an 8-bit image.
    pub fn from_gray8(img: &GrayImage) -> Result<Self> {
        let (w, h) = (img.width() as usize, img.height() as usize);
        if w == 0 || h == 0 {
            return Err(VisionError::BadImage { reason: format!("the image has no pixels ({w}x{h})") });
        }
        Ok(Self { width: w, height: h, data: img.as_raw().iter().map(|v| f32::from(*v)).collect() })
    }

    /// Wraps row-major values; the length must be `width * height > 0`.
    pub fn from_vec(width: usize, height: usize, data: Vec<f32>) -> Result<Self> {
        if width == 0 || height == 0 || data.len() != width * height {
            return Err(VisionError::BadImage {
                reason: format!("{} values for a {width}x{height} image", data.len()),
            });
        }
        Ok(Self { width, height, data })
    }

    /// The value at column `x`, row `y` (must be inside).
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Bilinear interpolation at `(x, y)` (pixel-centre convention), clamped to the image.
    pub fn bilinear(&self, x: f64, y: f64) -> f64 {
        let xc = x.clamp(0.0, (self.width - 1) as f64);
        let yc = y.clamp(0.0, (self.height - 1) as f64);
        // Non-negative after the clamp: truncation is the floor.
        let (x0, y0) = (xc as usize, yc as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (xc - x0 as f64, yc - y0 as f64);
        let a = f64::from(self.get(x0, y0)) * (1.0 - fx) + f64::from(self.get(x1, y0)) * fx;
        let b = f64::from(self.get(x0, y1)) * (1.0 - fx) + f64::from(self.get(x1, y1)) * fx;
        a * (1.0 - fy) + b * fy
    }

    /// Gaussian smoothing with standard deviation `sigma_px`: kornia-rs's kernel
    /// (`2 round(4 sigma) + 1` taps, single precision) and its zero padding (the outer
    /// `4 sigma` pixels are darkened: callers ignore them), the same sums in the same order as
    /// kornia's separable filter, over bands of rows in parallel.
    pub fn gaussian(&self, sigma_px: f64) -> Result<Self> {
        let sigma = sigma_px as f32;
        if !(sigma > 0.0 && sigma.is_finite()) {
            return Err(VisionError::BadOption {
                name: "sigma_px",
                value: sigma_px.to_string(),
                reason: "the Gaussian's width must be positive and finite".into(),
            });
        }
        let size = (2.0 * (4.0 * sigma).round() + 1.0) as usize | 1;
        let kernel = kornia_imgproc::filter::kernels::gaussian_kernel_1d(size, sigma);
        let half = (size / 2) as isize;
        let (w, h) = (self.width, self.height);
        // Along the rows.
        let mut tmp = vec![0.0f32; w * h];
        tmp.par_chunks_mut(w).zip(self.data.par_chunks(w)).for_each(|(out, row)| {
            for (c, o) in out.iter_mut().enumerate() {
                let mut acc = 0.0f32;
                let first = c as isize - half;
                if first >= 0 && first + size as isize <= w as isize {
                    for (v, k) in row[first as usize..first as usize + size].iter().zip(&kernel) {
                        acc += v * k;
                    }
                } else {
                    for (i, k) in kernel.iter().enumerate() {
                        let x = first + i as isize;
                        if x >= 0 && x < w as isize {
                            acc += row[x as usize] * k;
                        }
                    }
                }
                *o = acc;
            }
        });
        // Along the columns, a whole row at a time (the taps in the same order per pixel).
        let mut data = vec![0.0f32; w * h];
        data.par_chunks_mut(w).enumerate().for_each(|(r, out)| {
            for (i, k) in kernel.iter().enumerate() {
                let y = r as isize + i as isize - half;
                if y >= 0 && y < h as isize {
                    let src = &tmp[y as usize * w..(y as usize + 1) * w];
                    for (o, v) in out.iter_mut().zip(src) {
                        *o += v * k;
                    }
                }
            }
        });
        Ok(Self { width: w, height: h, data })
    }

    /// Halves the resolution by 2 x 2 averaging; pixel `(x, y)` of the result is centred on
    /// `(2x + 0.5, 2y + 0.5)` of this image.
    pub fn downsample2(&self) -> Self {
        let (w, h) = ((self.width / 2).max(1), (self.height / 2).max(1));
        let mut data = vec![0.0f32; w * h];
        for y in 0..h {
            let (y0, y1) = ((2 * y).min(self.height - 1), (2 * y + 1).min(self.height - 1));
            for x in 0..w {
                let (x0, x1) = ((2 * x).min(self.width - 1), (2 * x + 1).min(self.width - 1));
                data[y * w + x] = 0.25 * (self.get(x0, y0) + self.get(x1, y0) + self.get(x0, y1) + self.get(x1, y1));
            }
        }
        Self { width: w, height: h, data }
    }
}

/// Largest image this project decodes, in pixels (100 megapixels, e.g. 12000 x 8000: a
/// grey copy is 100 MB, a colour one 300 MB). The dimensions are read from the file's header
/// and checked before any pixel is decoded, so a small file that declares a huge image (a
/// 20000 x 20000 PNG of 389 KB) is refused without allocating gigabytes.
pub const MAX_IMAGE_PIXELS: u64 = 100_000_000;

/// Checks an image file before decoding: readable, a known format, dimensions within
/// [`MAX_IMAGE_PIXELS`], and for a JPEG complete (its end-of-image marker after its last scan:
/// a JPEG cut short decodes "successfully" with grey or smeared rows, and corners found in it are
/// wrong). Returns the width and height from the header; the error is the reason.
pub fn check_image_file(path: &Path) -> std::result::Result<(u32, u32), String> {
    let reader =
        image::ImageReader::open(path).map_err(|e| e.to_string())?.with_guessed_format().map_err(|e| e.to_string())?;
    let Some(format) = reader.format() else {
        return Err("not a recognised image format (PNG, JPEG, TIFF, BMP, PNM)".into());
    };
    let (w, h) = reader.into_dimensions().map_err(|e| format!("cannot decode the header: {e}"))?;
    if u64::from(w) * u64::from(h) > MAX_IMAGE_PIXELS {
        return Err(format!(
            "the image is {w} x {h} pixels, more than the limit of {MAX_IMAGE_PIXELS} pixels; refused before decoding"
        ));
    }
    if format == image::ImageFormat::Jpeg {
        let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
        if !jpeg_is_complete(&bytes) {
            return Err(format!(
                "the JPEG is truncated ({} bytes, no end-of-image marker after its last scan): was the file cut short?",
                bytes.len()
            ));
        }
    }
    Ok((w, h))
}

/// Whether a JPEG stream has its end-of-image marker (`FF D9`) after its last start-of-scan
/// (`FF DA`). Entropy-coded data never holds `FF D9` (a data byte `FF` is followed by `00`),
/// so the marker is found only when the file is complete; an embedded thumbnail's scan comes
/// before the main image's.
pub fn jpeg_is_complete(bytes: &[u8]) -> bool {
    let last_sos = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]);
    let Some(sos) = last_sos else { return false };
    bytes[sos..].windows(2).any(|w| w == [0xFF, 0xD9])
}

/// Reads an image file as 8-bit grey (colour images are converted with the `image` crate's
/// luma weights). An empty file, an undecodable file or a 0 x 0 image is an error naming the
/// file.
pub fn load_gray(path: impl AsRef<Path>) -> Result<GrayImage> {
    let path = path.as_ref();
    let fail =
        |reason: String| VisionError::ImageRead { path: path.to_path_buf(), reason: reason.trim().replace('\n', " ") };
    let meta = std::fs::metadata(path).map_err(|e| fail(e.to_string()))?;
    if meta.is_dir() {
        return Err(fail("is a directory".into()));
    }
    if meta.len() == 0 {
        return Err(fail("the file is empty (0 bytes)".into()));
    }
    check_image_file(path).map_err(fail)?;
    let reader = image::ImageReader::open(path)
        .map_err(|e| fail(e.to_string()))?
        .with_guessed_format()
        .map_err(|e| fail(e.to_string()))?;
    let img = reader.decode().map_err(|e| fail(format!("cannot decode: {e}")))?;
    if img.width() == 0 || img.height() == 0 {
        return Err(fail("the image has no pixels".into()));
    }
    Ok(to_gray(&img))
}

/// Grey level of a decoded image: 8-bit grey as is; colour by the JFIF / ITU-R BT.601 luma
/// `Y = 0.299 R + 0.587 G + 0.114 B` (the Y plane of a colour JPEG, which is what the AprilTag
/// library and OpenCV's `cvtColor(..., COLOR_RGB2GRAY)` use), rounded; alpha ignored; deeper
/// images scaled to 8 bits.
pub fn to_gray(img: &image::DynamicImage) -> GrayImage {
    use image::DynamicImage as D;
    match img {
        D::ImageLuma8(g) => g.clone(),
        D::ImageLuma16(_) | D::ImageLumaA8(_) | D::ImageLumaA16(_) => img.to_luma8(),
        _ => {
            let rgb = img.to_rgb8();
            let data = rgb
                .as_raw()
                .chunks_exact(3)
                .map(|p| {
                    (0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2]))
                        .round()
                        .clamp(0.0, 255.0) as u8
                })
                .collect();
            GrayImage::from_raw(rgb.width(), rgb.height(), data).expect("same size")
        }
    }
}

/// Per-pixel median of a sequence of equally sized images: the static background of a
/// recording (the Gantry-Tau method uses 10 frames).
pub fn median_background(frames: &[GrayImage]) -> Result<GrayImage> {
    let first =
        frames.first().ok_or_else(|| VisionError::BadImage { reason: "no frames for the background median".into() })?;
    let (w, h) = first.dimensions();
    if w == 0 || h == 0 {
        return Err(VisionError::BadImage { reason: "the first frame has no pixels".into() });
    }
    for (k, f) in frames.iter().enumerate() {
        if f.dimensions() != (w, h) {
            return Err(VisionError::BadImage {
                reason: format!("frame {k} is {}x{}, frame 0 is {w}x{h}", f.width(), f.height()),
            });
        }
    }
    let n = frames.len();
    let mut out = vec![0u8; (w * h) as usize];
    let mut buf = vec![0u8; n];
    for (i, o) in out.iter_mut().enumerate() {
        for (b, f) in buf.iter_mut().zip(frames) {
            *b = f.as_raw()[i];
        }
        buf.sort_unstable();
        *o =
            if n % 2 == 1 { buf[n / 2] } else { (u16::from(buf[n / 2 - 1]) + u16::from(buf[n / 2])).div_ceil(2) as u8 };
    }
    GrayImage::from_raw(w, h, out).ok_or_else(|| VisionError::BadImage { reason: "size overflow".into() })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = 0xFFFF_FFFFu32;
        for b in bytes {
            c ^= u32::from(*b);
            for _ in 0..8 {
                c = if c & 1 == 1 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }

    /// A PNG whose header declares `w` x `h` grey pixels (the data is not there).
    fn png_header(w: u32, h: u32) -> Vec<u8> {
        let mut out = vec![0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];
        let mut chunk = b"IHDR".to_vec();
        chunk.extend(w.to_be_bytes());
        chunk.extend(h.to_be_bytes());
        chunk.extend([8, 0, 0, 0, 0]);
        let mut push = |chunk: Vec<u8>| {
            out.extend((chunk.len() as u32 - 4).to_be_bytes());
            out.extend(&chunk);
            out.extend(crc32(&chunk).to_be_bytes());
        };
        push(chunk);
        let mut idat = b"IDAT".to_vec();
        idat.extend([0x78, 0x9C, 0x63, 0x00, 0x00, 0x00, 0x01, 0x00, 0x01]);
        push(idat);
        push(b"IEND".to_vec());
        out
    }

    #[test]
    fn image_over_the_pixel_limit_is_refused_before_decoding() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("huge.png");
        std::fs::write(&p, png_header(20_000, 20_000)).unwrap();
        let e = load_gray(&p).unwrap_err().to_string();
        assert!(e.contains("20000 x 20000") && e.contains("huge.png"), "{e}");
    }

    #[test]
    fn truncated_jpeg_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let img = image::GrayImage::from_fn(320, 240, |x, y| image::Luma([((x / 20 + y / 20) % 2 * 200 + 20) as u8]));
        let full = dir.path().join("board.jpg");
        img.save(&full).unwrap();
        assert_eq!(load_gray(&full).unwrap().dimensions(), (320, 240));
        let bytes = std::fs::read(&full).unwrap();
        let half = dir.path().join("half.jpg");
        std::fs::write(&half, &bytes[..bytes.len() / 2]).unwrap();
        let e = load_gray(&half).unwrap_err().to_string();
        assert!(e.contains("half.jpg") && e.contains("truncated"), "{e}");
        assert!(jpeg_is_complete(&bytes) && !jpeg_is_complete(&bytes[..bytes.len() - 1]));
    }
}
