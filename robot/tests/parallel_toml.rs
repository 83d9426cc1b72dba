//! TOML model files: the shipped files equal the presets, writing and reading round-trips, and
//! every kind of bad input gives an error naming the file, line, column and field.

use std::path::{Path, PathBuf};

use ferrocal_robot::error::Location;
use ferrocal_robot::geometry::pose_from_vectors;
use ferrocal_robot::parallel::file::{parse_str, to_toml_string};
use ferrocal_robot::presets::preset;
use ferrocal_robot::{Parameterized, RobotError, RobotModel};
use nalgebra::Vector3;

fn models_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("models")
}

fn same_model(a: &RobotModel, b: &RobotModel) -> bool {
    match (a, b) {
        (RobotModel::GantryTau3(x), RobotModel::GantryTau3(y)) => x == y,
        (RobotModel::GantryTau6(x), RobotModel::GantryTau6(y)) => x == y,
        (RobotModel::GantryTauF1(x), RobotModel::GantryTauF1(y)) => x == y,
        (RobotModel::Hexapod(x), RobotModel::Hexapod(y)) => x == y,
        _ => false,
    }
}

#[test]
fn shipped_model_files_equal_the_presets() {
    for name in ["gantry-tau-l1", "gantry-tau-l1-6link", "gantry-tau-f1", "hexapod"] {
        let path = models_dir().join(format!("{name}.toml"));
        let loaded = RobotModel::load(path.to_str().unwrap()).unwrap_or_else(|e| panic!("{name}: {e}"));
        let preset = preset(name).unwrap();
        assert!(same_model(&loaded, &preset), "{name}: the file differs from the preset");
        assert_eq!(loaded.name(), name);
    }
}

#[test]
fn written_models_read_back() {
    let file = Path::new("<memory>");
    for name in ["gantry-tau-l1", "gantry-tau-l1-6link", "gantry-tau-f1", "hexapod"] {
        let mut m = preset(name).unwrap();
        // Perturb every parameter and set the optional fields.
        let n = m.n_parameters();
        let delta: Vec<f64> = (0..n).map(|i| 1e-4 * ((i * 7919) % 13) as f64 / 13.0).collect();
        let values: Vec<f64> = m.parameter_values().iter().zip(&delta).map(|(a, b)| a + b).collect();
        m.set_parameter_values(&values).unwrap();
        let tool = pose_from_vectors(&Vector3::new(0.01, -0.02, 0.1), &Vector3::new(0.0, 0.0, 0.0));
        match &mut m {
            RobotModel::GantryTau3(k) => k.arms[1].base_axis = Some(Vector3::new(0.9, 0.1, -0.2)),
            RobotModel::GantryTau6(k) => {
                k.tool = tool;
                k.links[4].platform_axis = Some(Vector3::new(-1.0, 0.0, 0.1));
            }
            RobotModel::GantryTauF1(k) => k.tool = tool,
            RobotModel::Hexapod(k) => k.tool = tool,
            _ => unreachable!(),
        }
        let text = to_toml_string(&m).unwrap();
        let back = parse_str(&text, file).unwrap_or_else(|e| panic!("{name}: {e}\n{text}"));
        assert!(same_model(&back, &m), "{name}: written and read back differ\n{text}");
    }
}

const GT3: &str = r#"kind = "gantry_tau_3"
name = "test"
assembly = "plus"

[[arm]]
length_m = 2.0613
a_m = [-1.8093, 3.5095, 0.0041]
v = [1.0, 0.0, 0.0]
branch = "minus"
limits_m = [-1.0, 1.0]

[[arm]]
length_m = 2.0662
a_m = [-1.8688, 2.2455, 0.2075]
v = [1.0, 0.0, 0.0]
branch = "minus"
limits_m = [-1.0, 1.0]

[[arm]]
length_m = 2.0632
a_m = [-1.8109, 3.2774, -1.4436]
v = [1.0, 0.0, 0.0]
branch = "minus"
limits_m = [-1.0, 1.0]
"#;

fn parse(text: &str) -> Result<RobotModel, RobotError> {
    parse_str(text, Path::new("robots/test.toml"))
}

/// Line and column (1-based) of the first occurrence of `needle` after `after` in `text`.
fn position(text: &str, after: &str, needle: &str) -> (u32, u32) {
    let start = text.find(after).unwrap();
    let at = start + text[start..].find(needle).unwrap();
    let line = text[..at].matches('\n').count() + 1;
    let col = at - text[..at].rfind('\n').map_or(0, |i| i + 1) + 1;
    (line as u32, col as u32)
}

fn assert_at(loc: &Location, text: &str, after: &str, needle: &str) {
    let (line, column) = position(text, after, needle);
    assert_eq!(loc.file, Path::new("robots/test.toml"));
    assert_eq!((loc.line, loc.column), (line, column), "location of `{needle}`");
}

#[test]
fn the_reference_text_parses() {
    let m = parse(GT3).unwrap();
    assert_eq!(m.name(), "test");
    assert_eq!(m.parameter_values(), preset("gantry-tau-l1").unwrap().parameter_values());
}

#[test]
fn non_finite_number_is_located() {
    let text = GT3.replacen("a_m = [-1.8688, 2.2455, 0.2075]", "a_m = [-1.8688, nan, 0.2075]", 1);
    match parse(&text) {
        Err(e @ RobotError::NonFinite { .. }) => {
            let msg = e.to_string();
            let RobotError::NonFinite { location, what } = e else { unreachable!() };
            assert_at(&location, &text, "length_m = 2.0662", "nan");
            assert!(what.contains("arm 2") && what.contains("a_m"), "{what}");
            assert!(msg.starts_with("robots/test.toml:"), "{msg}");
        }
        other => panic!("expected NonFinite, got {other:?}"),
    }
    let text = GT3.replacen("length_m = 2.0632", "length_m = inf", 1);
    assert!(
        matches!(parse(&text), Err(RobotError::NonFinite { what, .. }) if what.contains("arm 3") && what.contains("length_m"))
    );
}

#[test]
fn inverted_limits_are_located() {
    let text = GT3.replacen(
        "limits_m = [-1.0, 1.0]\n\n[[arm]]\nlength_m = 2.0632",
        "limits_m = [1.0, -1.0]\n\n[[arm]]\nlength_m = 2.0632",
        1,
    );
    match parse(&text) {
        Err(RobotError::BadLimits { joint, lower, upper, location: Some(location) }) => {
            assert_eq!(joint, "cart2");
            assert_eq!((lower, upper), (1.0, -1.0));
            assert_at(&location, &text, "limits_m = [1.0, -1.0]", "[1.0, -1.0]");
        }
        other => panic!("expected BadLimits, got {other:?}"),
    }
}

#[test]
fn zero_direction_is_located() {
    let text = GT3.replacen(
        "v = [1.0, 0.0, 0.0]\nbranch = \"minus\"\nlimits_m = [-1.0, 1.0]\n\n[[arm]]\nlength_m = 2.0632",
        "v = [0.0, 0.0, 0.0]\nbranch = \"minus\"\nlimits_m = [-1.0, 1.0]\n\n[[arm]]\nlength_m = 2.0632",
        1,
    );
    match parse(&text) {
        Err(RobotError::Parse { location, message }) => {
            assert_at(&location, &text, "length_m = 2.0662", "[0.0, 0.0, 0.0]");
            assert!(
                message.contains("arm 2") && message.contains("`v`") && message.contains("zero length"),
                "{message}"
            );
        }
        other => panic!("expected Parse, got {other:?}"),
    }
}

#[test]
fn missing_field_is_named() {
    let text = GT3.replacen("length_m = 2.0632\n", "", 1);
    match parse(&text) {
        Err(RobotError::Parse { location, message }) => {
            assert!(message.contains("arm 3") && message.contains("missing field `length_m`"), "{message}");
            // Points at the [[arm]] header of the third arm.
            let third = text.match_indices("[[arm]]").nth(2).unwrap().0;
            let line = text[..third].matches('\n').count() as u32 + 1;
            assert_eq!((location.line, location.column), (line, 1));
        }
        other => panic!("expected Parse, got {other:?}"),
    }
    let text = GT3.replacen("assembly = \"plus\"\n", "", 1);
    assert!(
        matches!(parse(&text), Err(RobotError::Parse { message, .. }) if message.contains("missing field `assembly`"))
    );
    let hex = std::fs::read_to_string(models_dir().join("hexapod.toml")).unwrap();
    let text = hex.replacen("[home]", "[homer]", 1);
    assert!(
        matches!(parse(&text), Err(RobotError::Parse { message, .. }) if message.contains("unknown field `homer`"))
    );
    let f1 = std::fs::read_to_string(models_dir().join("gantry-tau-f1.toml")).unwrap();
    let cut = f1.find("[tilt3]").unwrap();
    let end = cut + f1[cut..].find("\n\n").unwrap();
    let text = format!("{}{}", &f1[..cut], &f1[end + 2..]);
    assert!(
        matches!(parse(&text), Err(RobotError::Parse { message, .. }) if message.contains("missing field `tilt3`"))
    );
}

#[test]
fn other_mistakes_give_clear_errors() {
    let cases: &[(&str, &str, &str)] = &[
        ("length_m = 2.0613", "lenght_m = 2.0613", "unknown field `lenght_m`"),
        ("kind = \"gantry_tau_3\"", "kind = \"delta\"", "unknown model kind 'delta'"),
        ("branch = \"minus\"", "branch = \"down\"", "must be \"plus\" or \"minus\""),
        ("length_m = 2.0613", "length_m = -2.0613", "must be positive"),
        ("length_m = 2.0613", "length_m = \"long\"", "expected a number"),
        ("a_m = [-1.8093, 3.5095, 0.0041]", "a_m = [-1.8093, 3.5095]", "expected 3 numbers"),
        ("limits_m = [-1.0, 1.0]", "limits_m = [-1.0, 1.0", "TOML syntax"),
    ];
    for (from, to, expect) in cases {
        let text = GT3.replacen(from, to, 1);
        match parse(&text) {
            Err(RobotError::Parse { message, location }) => {
                assert!(message.contains(expect), "`{to}`: {message}");
                assert!(location.line >= 1 && location.column >= 1);
            }
            other => panic!("`{to}`: expected Parse, got {other:?}"),
        }
    }
    // Two arms only.
    let cut = GT3.rfind("[[arm]]").unwrap();
    assert!(
        matches!(parse(&GT3[..cut]), Err(RobotError::Parse { message, .. }) if message.contains("expected 3 [[arm]] tables, found 2"))
    );
    // The six-link cluster layout is checked.
    let six = std::fs::read_to_string(models_dir().join("gantry-tau-l1-6link.toml")).unwrap();
    let text = six.replacen("arm = 2", "arm = 1", 1);
    assert!(
        matches!(parse(&text), Err(RobotError::Parse { message, .. }) if message.contains("1 on arm 1, 2 on arm 2"))
    );
    let text = six.replacen("arm = 2", "arm = 4", 1);
    assert!(matches!(parse(&text), Err(RobotError::Parse { message, .. }) if message.contains("must be 1, 2 or 3")));
    // A missing file and an unknown extension.
    assert!(matches!(RobotModel::load("/nonexistent/robot.toml"), Err(RobotError::Io { .. })));
}

#[test]
fn links_may_come_in_any_arm_order() {
    let six = std::fs::read_to_string(models_dir().join("gantry-tau-l1-6link.toml")).unwrap();
    // Move the single link of arm 1 to the end of the file.
    let first = six.find("[[link]]").unwrap();
    let second = first + 1 + six[first + 1..].find("[[link]]").unwrap();
    let text = format!("{}{}\n{}", &six[..first], &six[second..], &six[first..second]);
    let m = parse(&text).unwrap();
    assert!(same_model(&m, &preset("gantry-tau-l1-6link").unwrap()));
}
