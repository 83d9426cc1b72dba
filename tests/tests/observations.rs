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

/// `handeye --observations`: the corners of a rendered eye-to-hand recording
/// (`handeye simulate`, seed 4), found in its images by `handeye` and written out with
/// `--corners-out`, are given back as an observations file, the point ids renumbered as the
/// pattern numbers its corners (row by row; the points placed in the detector's frame, so the
/// transform is in the same target frame as from the images). The hand-eye transform agrees with the one from
/// the images within 1.5 of its stated sigmas (the images' run weighs each corner by the
/// detector's covariance, the file gives none: 0.1 px each), and both lie within 0.5 mm of the
/// truth.
#[test]
fn handeye_from_observations_agrees_with_handeye_from_images() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("rec");
    let out = run(ferrocal().args(["handeye", "simulate", "--mount", "eye-to-hand", "--seed", "4", "--out"]).arg(&dir));
    assert!(out.status.success());
    let truth = json(&dir.join("truth.json"));
    let pattern = truth["pattern"].as_str().unwrap();
    let common = |cmd: &mut std::process::Command| {
        cmd.arg("--poses")
            .arg(dir.join("poses.csv"))
            .args(["--pattern", pattern, "--mount", "eye-to-hand", "--robot-poses-as-measurements", "--no-physics"])
            .arg("--intrinsics")
            .arg(dir.join("camera.yaml"));
    };
    let (a, corners) = (tmp.path().join("images.json"), tmp.path().join("corners.json"));
    let mut cmd = ferrocal();
    cmd.args(["handeye", "--images"]).arg(dir.join("images"));
    common(&mut cmd);
    let out = run(cmd.arg("--json").arg(&a).arg("--corners-out").arg(&corners));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // chessboard:<cols>x<rows>:<square>mm: the detector's point ((c - (cols - 1) / 2) s,
    // ((rows - 1) / 2 - r) s, 0) (origin at the centre, y up) is the pattern's number r cols + c.
    let dims: Vec<&str> = pattern.split(':').collect();
    let (cols, rows) = dims[1].split_once('x').unwrap();
    let (cols, rows): (usize, usize) = (cols.parse().unwrap(), rows.parse().unwrap());
    let square_m: f64 = dims[2].trim_end_matches("mm").parse::<f64>().unwrap() * 1e-3;
    let c = json(&corners);
    let points = c["target_points_m"].as_array().unwrap();
    let mut csv = String::from("image,point_id,u_px,v_px\n");
    let mut size = String::new();
    for v in c["views"].as_array().unwrap() {
        size = format!("{}x{}", v["image_size"][0], v["image_size"][1]);
        for (id, px) in v["point_ids"].as_array().unwrap().iter().zip(v["corners_px"].as_array().unwrap()) {
            let p = &points[id.as_u64().unwrap() as usize];
            let c = p[0].as_f64().unwrap() / square_m + 0.5 * (cols as f64 - 1.0);
            let r = 0.5 * (rows as f64 - 1.0) - p[1].as_f64().unwrap() / square_m;
            let n = r.round() as usize * cols + c.round() as usize;
            csv.push_str(&format!("{},{n},{},{}\n", v["image"].as_str().unwrap(), px[0], px[1]));
        }
    }
    let obs = tmp.path().join("obs.csv");
    std::fs::write(&obs, csv).unwrap();
    let b = tmp.path().join("observations.json");
    let mut cmd = ferrocal();
    cmd.args(["handeye", "--observations"]).arg(&obs).args(["--image-size", &size]);
    common(&mut cmd);
    let out = run(cmd.arg("--json").arg(&b));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (ra, rb) = (json(&a), json(&b));
    assert_eq!(ra["per_image"].as_array().unwrap().len(), rb["per_image"].as_array().unwrap().len());
    let t = &truth["hand_eye"]["translation"];
    for i in 0..3 {
        let (ea, eb) = (
            ra["hand_eye"]["translation_mm"][i].as_f64().unwrap(),
            rb["hand_eye"]["translation_mm"][i].as_f64().unwrap(),
        );
        let std = ra["std"]["hand_eye"]["translation_mm"][i].as_f64().unwrap();
        let truth_mm = t[i].as_f64().unwrap() * 1e3;
        assert!((ea - eb).abs() < 1.5 * std, "coordinate {i}: {ea} from images, {eb} from observations (std {std})");
        assert!((eb - truth_mm).abs() < 0.5, "coordinate {i}: {eb} vs the truth {truth_mm}");
    }
}
