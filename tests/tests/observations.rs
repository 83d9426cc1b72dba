//! Detections made elsewhere (`camera calibrate --observations`, `shared/spec/cli.md`
//! "Observations instead of images"): the same corners as images, as the spec's CSV or as mrcal's
//! corners file, give the same camera to the last digit; bad files are named with their line.

use ferrocal_tests::{data, ferrocal, json, run};

const PATTERN: &str = "chessboard:9x6:25mm";

/// One image's corners by id: `(u, v)` as written, or `None`.
type Corners = Vec<Option<(String, String)>>;

/// The corners the calibration of OpenCV's left sample used, saved with `--save-observations`,
/// then read back as observations (image size from the image files, and given) and written by
/// this test as an mrcal corners file (`# filename x y level`, each board's 54 corners in order,
/// `- - -` for one not found): fx, fy, cx, cy, the RMS and every standard deviation are equal.
#[test]
fn the_same_corners_as_images_or_as_observations_give_the_same_camera() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let images = data("opencv_stereo").join("left*.jpg");
    let obs = t.join("obs.csv");
    let out = run(ferrocal()
        .args(["camera", "calibrate", "--images"])
        .arg(images.to_str().unwrap())
        .args(["--pattern", PATTERN, "--save-observations"])
        .arg(&obs)
        .arg("--json")
        .arg(t.join("images.json")));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(&obs).unwrap();
    assert!(csv.starts_with("image,camera,point_id,u_px,v_px\n"), "{}", &csv[..80]);
    // The mrcal corners file of the same detections.
    let mut by_image: Vec<(String, Corners)> = Vec::new();
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if by_image.last().is_none_or(|(name, _)| name != f[0]) {
            by_image.push((f[0].to_string(), vec![None; 54]));
        }
        let id: usize = f[2].parse().unwrap();
        by_image.last_mut().unwrap().1[id] = Some((f[3].to_string(), f[4].to_string()));
    }
    let mut vnl = String::from("# filename x y level\n");
    for (name, corners) in &by_image {
        for c in corners {
            match c {
                Some((u, v)) => vnl.push_str(&format!("{name} {u} {v} 0\n")),
                None => vnl.push_str(&format!("{name} - - -\n")),
            }
        }
    }
    let corners = t.join("corners.vnl");
    std::fs::write(&corners, vnl).unwrap();
    let reference = json(&t.join("images.json"));
    for (name, file, size) in [("csv", &obs, None), ("csv-sized", &obs, Some("640x480")), ("mrcal", &corners, None)] {
        let j = t.join(format!("{name}.json"));
        let mut cmd = ferrocal();
        cmd.args(["camera", "calibrate", "--observations"]).arg(file).args(["--pattern", PATTERN, "--json"]).arg(&j);
        if let Some(s) = size {
            cmd.args(["--image-size", s]);
        }
        let out = run(&mut cmd);
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        let v = json(&j);
        for key in ["fx", "fy", "cx", "cy", "rms_px", "std", "per_view"] {
            assert_eq!(v[key], reference[key], "{name}: {key}");
        }
        assert_eq!(v["corners"], "observations", "{name}");
    }
}

/// A point id the pattern does not have, a missing column and an unreadable number are refused
/// with the file, the line and the column or image; without readable images and no
/// `--image-size`, the error says to give it.
#[test]
fn bad_observations_are_named_with_their_line() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let cases = [
        ("ids.csv", "image,point_id,u_px,v_px\na.png,0,1,2\nb.png,54,3,4\n", vec!["ids.csv", "line 3", "b.png", "54"]),
        ("cols.csv", "image,point_id,u_px\na.png,0,1\n", vec!["cols.csv", "v_px"]),
        ("num.csv", "image,point_id,u_px,v_px\na.png,0,1,2\na.png,1,x,4\n", vec!["num.csv", "3", "u_px"]),
        ("size.csv", "image,point_id,u_px,v_px\nnowhere.png,0,1,2\n", vec!["size.csv", "--image-size"]),
    ];
    for (name, text, words) in cases {
        let f = t.join(name);
        std::fs::write(&f, text).unwrap();
        let mut cmd = ferrocal();
        cmd.args(["camera", "calibrate", "--observations"]).arg(&f).args(["--pattern", PATTERN]);
        if name != "size.csv" {
            cmd.args(["--image-size", "640x480"]);
        }
        let out = run(&mut cmd);
        assert!(!out.status.success(), "{name}");
        let err = String::from_utf8_lossy(&out.stderr);
        for w in words {
            assert!(err.contains(w), "{name}: '{w}' not in {err}");
        }
    }
}
