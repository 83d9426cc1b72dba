//! AprilTag families as the AprilTag C library defines them, and tag images drawn exactly as
//! its generator (`apriltag_to_image`) draws them.

use crate::error::{DatasetError, Result};

/// A tag family's codes and bit layout, copied from the AprilTag C library.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TagFamily {
    /// Family name, e.g. `tag36h11`.
    pub name: String,
    /// The codes; the tag id is the index.
    pub codes: Vec<u64>,
    /// Number of data bits per code.
    pub nbits: u32,
    /// Column of each data bit, in cells, counted from the outer edge of the black border.
    pub bit_x: Vec<u32>,
    /// Row of each data bit (downwards in the tag image), same origin as `bit_x`.
    pub bit_y: Vec<u32>,
    /// Width of the tag up to and including the black border, in cells (8 for tag36h11).
    pub width_at_border: u32,
    /// Width of the whole tag image including the white border, in cells (10 for tag36h11).
    pub total_width: u32,
    /// Whether the border is reversed (white inside, black outside), as in the "standard" and
    /// "circle" families.
    pub reversed_border: bool,
}

impl TagFamily {
    /// The tag36h11 family (587 codes) read from the AprilTag C library.
    pub fn tag36h11() -> Result<Self> {
        // SAFETY: `tag36h11_create` returns a newly allocated, fully initialised family (or
        // null). Its arrays hold `ncodes` codes and `nbits` bit coordinates; we copy them out
        // before handing the family back to `tag36h11_destroy`, and keep no pointer into it.
        unsafe {
            let fam = apriltag_sys::tag36h11_create();
            if fam.is_null() {
                return Err(DatasetError::Render("the AprilTag C library returned no tag36h11 family".into()));
            }
            let f = &*fam;
            let copy = || -> Option<TagFamily> {
                if f.codes.is_null() || f.bit_x.is_null() || f.bit_y.is_null() || f.nbits > 64 {
                    return None;
                }
                let codes = std::slice::from_raw_parts(f.codes, f.ncodes as usize).to_vec();
                let bit_x = std::slice::from_raw_parts(f.bit_x, f.nbits as usize).to_vec();
                let bit_y = std::slice::from_raw_parts(f.bit_y, f.nbits as usize).to_vec();
                let name = if f.name.is_null() {
                    "tag36h11".to_string()
                } else {
                    std::ffi::CStr::from_ptr(f.name).to_string_lossy().into_owned()
                };
                Some(TagFamily {
                    name,
                    codes,
                    nbits: f.nbits,
                    bit_x,
                    bit_y,
                    width_at_border: u32::try_from(f.width_at_border).ok()?,
                    total_width: u32::try_from(f.total_width).ok()?,
                    reversed_border: f.reversed_border,
                })
            };
            let out = copy();
            apriltag_sys::tag36h11_destroy(fam);
            out.ok_or_else(|| DatasetError::Render("the AprilTag C library's tag36h11 family is malformed".into()))
        }
    }

    /// The tag image of `id`: `total_width x total_width` cells, row-major, top row first,
    /// `true` for white. Drawn exactly as the C library's `apriltag_to_image`: every cell
    /// black, then a one-cell white ring of width `width_at_border + 2` (`width_at_border` for
    /// reversed borders) centred in the image, then each data bit `i` whose code bit
    /// `nbits - 1 - i` is set painted white at `(bit_x[i], bit_y[i])` offset by
    /// `(total_width - width_at_border) / 2`.
    pub fn tag_cells(&self, id: u32) -> Result<Vec<bool>> {
        let code = *self.codes.get(id as usize).ok_or_else(|| DatasetError::RenderConfig {
            field: "target.ids".into(),
            value: id.to_string(),
            reason: format!("{} has ids 0..{}", self.name, self.codes.len()),
        })?;
        let t = self.total_width as usize;
        let mut im = vec![false; t * t];
        let white_width = self.width_at_border as usize + if self.reversed_border { 0 } else { 2 };
        if white_width > t {
            return Err(DatasetError::Render(format!("{}: white border wider than the tag image", self.name)));
        }
        let ws = (t - white_width) / 2;
        for i in 0..white_width.saturating_sub(1) {
            im[ws * t + ws + i] = true;
            im[(ws + i) * t + t - 1 - ws] = true;
            im[(t - 1 - ws) * t + ws + i + 1] = true;
            im[(ws + 1 + i) * t + ws] = true;
        }
        let bs = (t - self.width_at_border as usize) / 2;
        for i in 0..self.nbits as usize {
            if code & (1u64 << (self.nbits as usize - i - 1)) != 0 {
                let x = self.bit_x[i] as usize + bs;
                let y = self.bit_y[i] as usize + bs;
                if x >= t || y >= t {
                    return Err(DatasetError::Render(format!("{}: bit {i} lies outside the tag image", self.name)));
                }
                im[y * t + x] = true;
            }
        }
        Ok(im)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tag36h11_layout_from_the_c_library() {
        let f = TagFamily::tag36h11().unwrap();
        assert_eq!(f.name, "tag36h11");
        assert_eq!(f.codes.len(), 587);
        assert_eq!((f.nbits, f.width_at_border, f.total_width, f.reversed_border), (36, 8, 10, false));
        let cells = f.tag_cells(0).unwrap();
        // White outer ring, black ring inside it.
        for k in 0..10 {
            assert!(cells[k] && cells[90 + k] && cells[k * 10] && cells[k * 10 + 9]);
        }
        for k in 1..9 {
            assert!(!cells[10 + k] && !cells[80 + k] && !cells[k * 10 + 1] && !cells[k * 10 + 8]);
        }
        // The 36 data cells carry the code, most significant bit first.
        let mut code = 0u64;
        for i in 0..36 {
            let (x, y) = (f.bit_x[i] as usize + 1, f.bit_y[i] as usize + 1);
            code = (code << 1) | u64::from(cells[y * 10 + x]);
        }
        assert_eq!(code, f.codes[0]);
        assert!(f.tag_cells(587).is_err());
    }
}
