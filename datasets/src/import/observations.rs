//! Detections made elsewhere (`--observations`, `shared/spec/cli.md` "Observations instead of
//! images"): one row per detected point, `image, camera, point_id, u_px, v_px` and optionally
//! `sigma_px`; or mrcal's corners files (`# filename x y level`, one line per chessboard corner
//! in the board's order, `- -` for a corner or an image without detections).
//!
//! Every error names the file, the line and the column. Images keep the order of their first
//! row; the rows of one image may come in any order.

use std::path::Path;

use nalgebra::Point2;

use super::table::{read_text, Table, TableFormat};
use crate::error::{DatasetError, Location, Result};

/// One image's detected points.
#[derive(Clone, Debug, PartialEq)]
pub struct ObservedImage {
    /// The image's name (its file name or path, as the file gives it).
    pub image: String,
    /// The camera that took it (`""` when the file has no camera column).
    pub camera: String,
    /// Which target point each detection is.
    pub point_ids: Vec<usize>,
    /// The detections, pixels.
    pub corners_px: Vec<Point2<f64>>,
    /// Each detection's standard deviation per axis, pixels, when given.
    pub sigma_px: Vec<Option<f64>>,
    /// The line of the image's first row (1-based), for messages.
    pub line: u64,
}

/// The observations of a file, images in the order of their first row.
#[derive(Clone, Debug, PartialEq)]
pub struct Observations {
    /// The images.
    pub images: Vec<ObservedImage>,
}

impl Observations {
    /// The cameras named, in the order they first appear.
    pub fn cameras(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for i in &self.images {
            if !out.contains(&i.camera) {
                out.push(i.camera.clone());
            }
        }
        out
    }
}

/// Reads an observations file: mrcal's corners format when its first line is
/// `# filename x y ...`, else the CSV of the spec.
pub fn read_observations(path: &Path) -> Result<Observations> {
    let text = read_text(path)?;
    let first = text.lines().next().unwrap_or("");
    if first.trim_start().starts_with('#') && first.split_whitespace().skip(1).take(3).eq(["filename", "x", "y"]) {
        parse_mrcal_corners(&text, path)
    } else {
        parse_observations_csv(&text, path)
    }
}

fn image_slot<'a>(images: &'a mut Vec<ObservedImage>, image: &str, camera: &str, line: u64) -> &'a mut ObservedImage {
    let k = match images.iter().position(|i| i.image == image && i.camera == camera) {
        Some(k) => k,
        None => {
            images.push(ObservedImage {
                image: image.to_string(),
                camera: camera.to_string(),
                point_ids: Vec::new(),
                corners_px: Vec::new(),
                sigma_px: Vec::new(),
                line,
            });
            images.len() - 1
        }
    };
    &mut images[k]
}

fn parse_observations_csv(text: &str, path: &Path) -> Result<Observations> {
    let numeric = |h: &str| matches!(h, "point_id" | "u_px" | "v_px" | "sigma_px");
    let table = Table::parse(text, path, TableFormat::CSV, &numeric)?;
    let image_col = table.require("image")?;
    let id_col = table.require("point_id")?;
    let u_col = table.require("u_px")?;
    let v_col = table.require("v_px")?;
    let camera_col = table.col("camera");
    let sigma_col = table.col("sigma_px");
    let mut images: Vec<ObservedImage> = Vec::new();
    for row in &table.rows {
        let image = table.text(row, image_col)?;
        let camera = match camera_col {
            Some(c) => table.text(row, c)?,
            None => "",
        };
        let id = table.number(row, id_col)?;
        if id < 0.0 || id.fract() != 0.0 || id > u32::MAX as f64 {
            return Err(DatasetError::Invalid {
                location: table.loc(row, id_col),
                message: format!("point_id {id} is not a whole number from 0"),
            });
        }
        let (u, v) = (table.number(row, u_col)?, table.number(row, v_col)?);
        let sigma = match sigma_col {
            Some(c) => table.opt_number(row, c)?,
            None => None,
        };
        if let Some(s) = sigma.filter(|s| !(*s > 0.0 && s.is_finite())) {
            return Err(DatasetError::Invalid {
                location: table.loc(row, sigma_col.unwrap_or(u_col)),
                message: format!("sigma_px {s} is not a positive number"),
            });
        }
        let slot = image_slot(&mut images, image, camera, row.line);
        let id = id as usize;
        if slot.point_ids.contains(&id) {
            return Err(DatasetError::Invalid {
                location: table.loc(row, id_col),
                message: format!("point {id} of image '{image}' is given twice"),
            });
        }
        slot.point_ids.push(id);
        slot.corners_px.push(Point2::new(u, v));
        slot.sigma_px.push(sigma);
    }
    Ok(Observations { images })
}

/// mrcal's corners file: `filename x y [level]` per line, the corners of one image on
/// consecutive lines in the board's order (point ids 0, 1, ...), `filename - -` for an image
/// without detections; a corner with `-` coordinates or level is not observed.
fn parse_mrcal_corners(text: &str, path: &Path) -> Result<Observations> {
    let mut images: Vec<ObservedImage> = Vec::new();
    let mut next_id: Vec<usize> = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let n = k as u64 + 1;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let f: Vec<&str> = t.split_whitespace().collect();
        if f.len() < 3 {
            return Err(DatasetError::Invalid {
                location: Location::line(path, n),
                message: format!("{} field(s); mrcal's corners lines are 'filename x y [level]'", f.len()),
            });
        }
        let fresh = images.last().is_none_or(|i| i.image != f[0]);
        if fresh && images.iter().any(|i| i.image == f[0]) {
            return Err(DatasetError::Invalid {
                location: Location::new(path, n, "filename"),
                message: format!("image '{}' appears again after other images: its corners must be consecutive", f[0]),
            });
        }
        if fresh {
            images.push(ObservedImage {
                image: f[0].to_string(),
                camera: String::new(),
                point_ids: Vec::new(),
                corners_px: Vec::new(),
                sigma_px: Vec::new(),
                line: n,
            });
            next_id.push(0);
        }
        let k_img = images.len() - 1;
        if f[1] == "-" && f[2] == "-" && fresh && f.len() == 3 {
            // An image without detections.
            continue;
        }
        let id = next_id[k_img];
        next_id[k_img] += 1;
        if f[1] == "-" || f[2] == "-" || f.get(3) == Some(&"-") {
            continue;
        }
        let num = |s: &str, col: &str| -> Result<f64> {
            s.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| DatasetError::Invalid {
                location: Location::new(path, n, col),
                message: format!("'{s}' is not a number"),
            })
        };
        let (u, v) = (num(f[1], "x")?, num(f[2], "y")?);
        let level = f.get(3).map(|s| num(s, "level")).transpose()?;
        let img = &mut images[k_img];
        img.point_ids.push(id);
        img.corners_px.push(Point2::new(u, v));
        // mrcal weighs a corner found at decimation level l by 2^-l: its sigma grows by 2^l.
        img.sigma_px.push(level.filter(|l| *l > 0.0).map(|l| 2f64.powf(l)));
    }
    Ok(Observations { images })
}

/// Parses `--image-size`'s `<width>x<height>` (pixels).
pub fn parse_image_size(text: &str) -> Result<ferrocal_vision::camera::ImageSize> {
    let parsed: Option<(u32, u32)> =
        text.split_once(['x', 'X']).and_then(|(w, h)| Some((w.trim().parse().ok()?, h.trim().parse().ok()?)));
    match parsed {
        Some((w, h)) if w > 0 && h > 0 => Ok(ferrocal_vision::camera::ImageSize { width_px: w, height_px: h }),
        _ => Err(DatasetError::Input(format!(
            "--image-size '{text}': expected <width>x<height> in pixels, e.g. 640x480"
        ))),
    }
}

/// The size of the first of `obs`'s images that is readable as an image file (a relative name
/// taken beside `file`, then as given).
pub fn image_size_beside(obs: &Observations, file: &Path) -> Option<ferrocal_vision::camera::ImageSize> {
    let dir = file.parent().unwrap_or(Path::new("."));
    obs.images.iter().find_map(|i| {
        let p = Path::new(&i.image);
        let (w, h) = image::image_dimensions(dir.join(p)).or_else(|_| image::image_dimensions(p)).ok()?;
        Some(ferrocal_vision::camera::ImageSize { width_px: w, height_px: h })
    })
}

/// Writes observations as the spec's CSV (`image, camera, point_id, u_px, v_px[, sigma_px]`),
/// numbers in their shortest exact form, so that reading them back gives the same values.
pub fn observations_to_csv(obs: &Observations) -> String {
    let with_sigma = obs.images.iter().any(|i| i.sigma_px.iter().any(Option::is_some));
    let mut s = String::from("image,camera,point_id,u_px,v_px");
    if with_sigma {
        s.push_str(",sigma_px");
    }
    s.push('\n');
    for i in &obs.images {
        for ((id, p), sigma) in i.point_ids.iter().zip(&i.corners_px).zip(&i.sigma_px) {
            s.push_str(&format!("{},{},{id},{},{}", i.image, i.camera, p.x, p.y));
            if with_sigma {
                s.push_str(&sigma.map_or(String::new(), |v| format!(",{v}")));
                if sigma.is_none() {
                    s.push(',');
                }
            }
            s.push('\n');
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_csv_and_mrcal_forms_read_the_same_corners() {
        let csv = "image,camera,point_id,u_px,v_px\na.png,left,1,10.5,20.25\na.png,left,0,1,2\nb.png,left,0,3,4\n";
        let o = parse_observations_csv(csv, Path::new("obs.csv")).unwrap();
        assert_eq!(o.images.len(), 2);
        assert_eq!(o.images[0].point_ids, vec![1, 0]);
        assert_eq!(o.images[0].corners_px[0], Point2::new(10.5, 20.25));
        let mrcal = "# filename x y level\na.png 1 2 0\na.png 10.5 20.25 0\nc.png - -\nb.png 3 4 0\nb.png - - -\n";
        let m = parse_mrcal_corners(mrcal, Path::new("corners.vnl")).unwrap();
        assert_eq!(m.images.len(), 3);
        assert_eq!(m.images[0].point_ids, vec![0, 1]);
        assert!(m.images[1].point_ids.is_empty());
        assert_eq!(m.images[2].point_ids, vec![0]);
        // The CSV written back reads the same values.
        let back = parse_observations_csv(&observations_to_csv(&o), Path::new("x.csv")).unwrap();
        assert_eq!(back, o);
    }

    #[test]
    fn bad_rows_name_the_file_line_and_column() {
        let e = parse_observations_csv("image,point_id,u_px,v_px\na.png,1.5,1,2\n", Path::new("obs.csv")).unwrap_err();
        let m = e.to_string();
        assert!(m.contains("obs.csv") && m.contains('2') && m.contains("point_id"), "{m}");
        let e = parse_observations_csv("image,point_id,u_px,v_px\na.png,1,x,2\n", Path::new("obs.csv")).unwrap_err();
        assert!(e.to_string().contains("u_px"), "{e}");
        let e = parse_mrcal_corners("# filename x y level\na.png 1 zz 0\n", Path::new("c.vnl")).unwrap_err();
        assert!(e.to_string().contains("c.vnl") && e.to_string().contains('y'), "{e}");
    }
}
