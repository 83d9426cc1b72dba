//! Image folders with an optional joints table (data: OpenCV's stereo calibration sample,
//! Apache-2.0; NASA Swarmathon photos, CC BY-SA 2.0).

use std::cmp::Ordering;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use ferrocal_datasets::error::DatasetError;
use ferrocal_datasets::import::{
    list_images, natural_cmp, read_joints_table, write_joints_table, ImageFolderOptions, JointUnit,
};

const STEREO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/opencv_stereo");
const NASA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/apriltag_nasa");

fn names(paths: impl Iterator<Item = PathBuf>) -> Vec<String> {
    paths.map(|p| p.file_name().unwrap().to_string_lossy().to_string()).collect()
}

#[test]
fn lists_the_opencv_stereo_folder_in_natural_order() {
    let f = list_images(STEREO, &ImageFolderOptions::default()).unwrap();
    assert!(f.skipped.is_empty(), "{}", f.skipped_report());
    assert_eq!(f.images.len(), 26);
    let got = names(f.images.iter().map(|e| e.path.clone()));
    let mut want: Vec<String> = Vec::new();
    for side in ["left", "right"] {
        for i in (1..=14).filter(|i| *i != 10) {
            want.push(format!("{side}{i:02}.jpg"));
        }
    }
    assert_eq!(got, want);
    assert!(f.images.iter().all(|e| (e.width_px, e.height_px) == (640, 480) && e.q.is_none()));

    // A glob pattern.
    let f = list_images(format!("{STEREO}/left*.jpg"), &ImageFolderOptions::default()).unwrap();
    assert_eq!(f.images.len(), 13);
    assert_eq!(f.images[0].file_name, "left01.jpg");
    assert_eq!(f.images[12].file_name, "left14.jpg");
}

#[test]
fn lists_only_images_and_ignores_label_files() {
    let f = list_images(NASA, &ImageFolderOptions::default()).unwrap();
    assert_eq!(
        names(f.images.iter().map(|e| e.path.clone())),
        vec!["33369213973_9d9bb4cc96_c.jpg", "34085369442_304b6bafd9_c.jpg", "34139872896_defdb2f8d9_c.jpg"]
    );
    assert!(f.skipped.is_empty());
}

#[test]
fn natural_order() {
    let mut v = vec!["img10.png", "img2.png", "img1.png", "img02.png", "a.png", "img1b.png", "IMG3.png"];
    v.sort_by(|a, b| natural_cmp(a, b));
    assert_eq!(v, vec!["IMG3.png", "a.png", "img1.png", "img1b.png", "img02.png", "img2.png", "img10.png"]);
    assert_eq!(natural_cmp("x9", "x10"), Ordering::Less);
    assert_eq!(natural_cmp("x010", "x10"), Ordering::Less);
    assert_eq!(natural_cmp("x10", "x10"), Ordering::Equal);
}

/// A temp folder with readable images, an unreadable one, a truncated one and a text file.
fn fixture() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let img = image::RgbImage::from_fn(32, 24, |x, y| image::Rgb([(x * 8) as u8, (y * 10) as u8, 99]));
    for name in ["img1.png", "img2.png", "img10.png", "img3.bmp"] {
        img.save(dir.path().join(name)).unwrap();
    }
    std::fs::write(dir.path().join("broken.png"), b"this is not a PNG file").unwrap();
    let mut jpg = Vec::new();
    image::DynamicImage::ImageRgb8(img).write_to(&mut Cursor::new(&mut jpg), image::ImageFormat::Jpeg).unwrap();
    std::fs::write(dir.path().join("truncated.jpg"), &jpg[..jpg.len() / 2]).unwrap();
    std::fs::write(dir.path().join("notes.txt"), "not an image").unwrap();
    dir
}

#[test]
fn unreadable_images_are_reported_and_skipped() {
    let dir = fixture();
    let f = list_images(dir.path(), &ImageFolderOptions::default()).unwrap();
    assert_eq!(names(f.images.iter().map(|e| e.path.clone())), vec!["img1.png", "img2.png", "img3.bmp", "img10.png"]);
    assert!(f.images.iter().all(|e| (e.width_px, e.height_px) == (32, 24)));
    assert_eq!(names(f.skipped.iter().map(|s| s.path.clone())), vec!["broken.png", "truncated.jpg"]);
    let report = f.skipped_report();
    println!("{report}");
    assert!(report.contains(&dir.path().join("broken.png").display().to_string()));
    assert!(report.contains("truncated.jpg: cannot decode"), "{report}");
    assert!(f.skipped.iter().all(|s| !s.reason.is_empty()));
}

fn write_table(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("joints.csv");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn joints_table_is_matched_by_file_name() {
    let dir = fixture();
    let table = write_table(
        dir.path(),
        "# joints per image\nimage,q2_deg,q1_rad,q3_mm,note\nimg10.png,90,0.5,250,last\nimg1.png,-45,0,0,\nbroken.png,0,0,0,unreadable but present\n",
    );
    let opts = ImageFolderOptions { joints_table: Some(table.clone()), decode: true };
    let f = list_images(dir.path(), &opts).unwrap();
    assert_eq!(f.joint_units, vec![JointUnit::Rad, JointUnit::Deg, JointUnit::Mm]);
    let by_name = |n: &str| f.images.iter().find(|e| e.file_name == n).unwrap();
    assert_eq!(by_name("img10.png").q, Some(vec![0.5, 90f64.to_radians(), 0.25]));
    assert_eq!(by_name("img10.png").joints_line, Some(3));
    assert_eq!(by_name("img1.png").q, Some(vec![0.0, (-45f64).to_radians(), 0.0]));
    assert_eq!(by_name("img2.png").q, None);
    assert_eq!(f.skipped.len(), 2);

    // Written back and read again.
    let out = dir.path().join("joints_out.csv");
    write_joints_table(&out, &f, &[JointUnit::Rad, JointUnit::Rad, JointUnit::M]).unwrap();
    let back = read_joints_table(&out).unwrap();
    assert_eq!(back.rows.len(), 2);
    assert_eq!(back.rows[0].image, "img1.png");
    assert_eq!(back.rows[1].q, vec![0.5, 90f64.to_radians(), 0.25]);
}

#[test]
fn joints_table_naming_a_missing_file_names_table_line_and_column() {
    let dir = fixture();
    let table = write_table(dir.path(), "image,q1_deg,q2_deg\n# comment\nimg1.png,1,2\nimg99.png,3,4\n");
    let opts = ImageFolderOptions { joints_table: Some(table.clone()), decode: true };
    let e = list_images(dir.path(), &opts).unwrap_err();
    assert!(matches!(e, DatasetError::MissingFile { .. }), "{e:?}");
    let msg = e.to_string();
    assert!(
        msg.contains(&format!("{}: line 4, column 'image'", table.display()))
            && msg.contains("'img99.png' does not exist"),
        "{msg}"
    );
}

#[test]
fn bad_joints_tables_name_file_line_and_column() {
    let dir = fixture();
    let cases = [
        ("img,q1_deg\nimg1.png,1\n", 1, "image", "required column is missing"),
        ("image,q1_deg\nimg1.png,\"1,5\"\n", 2, "q1_deg", "decimal comma"),
        ("image,q1_deg,q2_deg\nimg1.png,1,5,2\n", 2, "q1_deg", "decimal comma"),
        ("image,q1_deg\nimg1.png,inf\n", 2, "q1_deg", "non-finite"),
        ("image,q1_deg,q3_deg\nimg1.png,1,2\n", 1, "q2_<unit>", "inconsistent joint count"),
        ("image,q1_deg\nimg1.png,1\nimg1.png,2\n", 3, "image", "already has joints on line 2"),
    ];
    for (text, line, column, words) in cases {
        let table = write_table(dir.path(), text);
        let opts = ImageFolderOptions { joints_table: Some(table.clone()), decode: false };
        let msg = list_images(dir.path(), &opts).unwrap_err().to_string();
        assert!(
            msg.contains(&format!("{}: line {line}, column '{column}'", table.display())) && msg.contains(words),
            "{text:?}: {msg}"
        );
    }
    // A folder that does not exist.
    let e = list_images(dir.path().join("nope"), &ImageFolderOptions::default()).unwrap_err();
    assert!(e.to_string().contains("nope"));
}
