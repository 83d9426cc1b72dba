//! Detects a pattern in one image and writes a copy with the corners marked.
//!
//! `cargo run --release -p ferrocal-vision --example detect_image -- <image> <pattern> [out.png]`
//! e.g. `... -- ../shared/data/opencv_stereo/left01.jpg chessboard:9x6:25mm /tmp/left01.png`

use ferrocal_vision::detect::{detect, load_gray, DetectOptions, Pattern};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        return Err("usage: detect_image <image> <pattern> [out.png]".into());
    }
    let img = load_gray(&args[0])?;
    let pattern: Pattern = args[1].parse()?;
    let found = detect(&img, &pattern, &DetectOptions::default(), None)?;
    let mut rgb = image::DynamicImage::ImageLuma8(img).to_rgb8();
    for d in &found {
        for (k, c) in d.corners.iter().enumerate() {
            let sd = c.covariance_px2.map(|m| m.trace().sqrt());
            println!(
                "id {:?} corner {k}: ({:.3}, {:.3}) px{}",
                d.id,
                c.position_px.x,
                c.position_px.y,
                sd.map_or(String::new(), |s| format!(", sigma {s:.4} px"))
            );
            let (x, y) = (c.position_px.x.round() as i64, c.position_px.y.round() as i64);
            for t in -4i64..=4 {
                for (xx, yy) in [(x + t, y), (x, y + t)] {
                    if xx >= 0 && yy >= 0 && (xx as u32) < rgb.width() && (yy as u32) < rgb.height() {
                        rgb.put_pixel(xx as u32, yy as u32, image::Rgb([255, 0, 0]));
                    }
                }
            }
        }
    }
    if let Some(out) = args.get(2) {
        rgb.save(out)?;
    }
    Ok(())
}
