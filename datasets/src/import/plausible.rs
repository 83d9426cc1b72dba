//! Plausibility checks at the boundary: values that parse but cannot be what the user meant
//! (joint readings far outside the model's limits, often degrees under a `_rad` header; a table
//! cut short in its last number; a pose set of one repeated pose), and the cutting of long cells
//! in messages. `docs/reliability.md` lists the inputs and what happens to each.

use std::collections::HashSet;

use ferrocal_calib::PoseMeasurement;
use ferrocal_robot::{JointKind, JointLimits};

use super::measurements::MeasurementTable;
use super::table::Table;
use super::units::{JointUnit, LengthUnit};
use crate::error::{DatasetError, Location, Result};

/// Longest cell text an error message repeats; longer cells are cut with an ellipsis and their
/// length (a 50 MB number is not echoed whole).
pub const MAX_ECHO_CHARS: usize = 60;

/// Largest plausible position coordinate in a measurement table, metres (10 km).
pub const MAX_POSITION_M: f64 = 1e4;

/// Largest plausible joint value of any table, in SI units (rad or m); beyond it a value is
/// refused even before a robot model is known.
pub const MAX_JOINT_SI: f64 = 1e4;

/// Slack beyond a joint's limits before a reading is refused: 0.1 rad (5.7 deg) for revolute
/// joints, 10 mm for prismatic ones (readings a little past a soft limit are real).
pub const LIMIT_SLACK_RAD: f64 = 0.1;
/// See [`LIMIT_SLACK_RAD`].
pub const LIMIT_SLACK_M: f64 = 0.01;

/// Range assumed for a joint without limits: four turns either way for revolute joints, 100 m
/// for prismatic ones.
pub const UNLIMITED_RAD: f64 = 8.0 * std::f64::consts::PI;
/// See [`UNLIMITED_RAD`].
pub const UNLIMITED_M: f64 = 100.0;

/// Joint configurations closer than this (rad or m, every joint) are the same pose.
pub const SAME_POSE_SI: f64 = 1e-6;

/// `text` cut to [`MAX_ECHO_CHARS`] characters, with an ellipsis and the full length when cut.
pub fn cut_cell(text: &str) -> String {
    let n = text.chars().count();
    if n <= MAX_ECHO_CHARS {
        return text.to_string();
    }
    let head: String = text.chars().take(MAX_ECHO_CHARS).collect();
    format!("{head}... ({n} characters)")
}

/// The range a joint reading may take: the limits widened by the slack, or the assumed range of
/// an unlimited joint.
fn allowed(limits: &JointLimits, kind: JointKind) -> (f64, f64) {
    let (slack, unlimited) = match kind {
        JointKind::Revolute => (LIMIT_SLACK_RAD, UNLIMITED_RAD),
        JointKind::Prismatic => (LIMIT_SLACK_M, UNLIMITED_M),
    };
    let lo = if limits.lower.is_finite() { limits.lower - slack } else { -unlimited };
    let hi = if limits.upper.is_finite() { limits.upper + slack } else { unlimited };
    (lo, hi)
}

impl MeasurementTable {
    /// Checks every joint reading against the model's limits (widened by [`LIMIT_SLACK_RAD`] /
    /// [`LIMIT_SLACK_M`]; [`UNLIMITED_RAD`] / [`UNLIMITED_M`] for unlimited joints). The error
    /// names the file, the first offending line and the column, counts the offending rows of
    /// that column, and suggests the unit when the values fit the limits in another one
    /// (degrees under a `_rad` header, millimetres under `_m`). Call after
    /// [`check_joint_kinds`](Self::check_joint_kinds).
    pub fn check_joint_values(&self, limits: &[JointLimits], model: &str) -> Result<()> {
        for (i, (unit, lim)) in self.joint_units.iter().zip(limits).enumerate() {
            let (lo, hi) = allowed(lim, unit.kind());
            let inside = |v: f64| v >= lo && v <= hi;
            let bad: Vec<&PoseMeasurement> = self.set.rows.iter().filter(|r| !inside(r.q[i])).collect();
            let Some(first) = bad.first() else { continue };
            let column = format!("q{}_{}", i + 1, unit.suffix());
            let shown = unit.from_si(first.q[i]);
            let (alt, alt_si): (Option<JointUnit>, fn(f64) -> f64) = match unit {
                JointUnit::Rad => (Some(JointUnit::Deg), f64::to_radians),
                JointUnit::M => (Some(JointUnit::Mm), |v| v / 1000.0),
                JointUnit::Deg | JointUnit::Mm => (None, |v| v),
            };
            // The other unit fits every row of the column (the column is in it), or at least
            // the offending rows (some rows are in it).
            let fits = |rows: &[&PoseMeasurement]| rows.iter().all(|r| inside(alt_si(unit.from_si(r.q[i]))));
            let all: Vec<&PoseMeasurement> = self.set.rows.iter().collect();
            let n = self.set.rows.len();
            let mut hint = String::new();
            if let Some(a) = alt {
                let name = if a == JointUnit::Deg { "degrees" } else { "millimetres" };
                // Nearly every row has some joint outside and every row fits as the other unit:
                // the columns are in it (one column alone is not enough: small angles in
                // degrees fit the limits in radians too).
                if 10 * self.rows_outside(limits) >= 9 * n && fits(&all) {
                    hint = format!("; the values look like {name}: name the column q{}_{}", i + 1, a.suffix());
                } else if fits(&bad) {
                    hint = format!(
                        "; these rows look like {name} while the others do not: convert them to {} (one unit per column)",
                        unit.suffix()
                    );
                }
            }
            let u = unit.suffix();
            let limits_text = if lim.lower.is_finite() && lim.upper.is_finite() {
                format!(
                    "the limits [{:.4}, {:.4}] {u} of robot model '{model}'",
                    unit.from_si(lim.lower),
                    unit.from_si(lim.upper)
                )
            } else {
                format!(
                    "[{:.4}, {:.4}] {u}, the range assumed for an unlimited joint of robot model '{model}'",
                    unit.from_si(lo),
                    unit.from_si(hi)
                )
            };
            return Err(DatasetError::Invalid {
                location: Location::new(&self.file, first.source_line.unwrap_or(0), column),
                message: format!(
                    "joint {} reads {shown} {u}, outside {limits_text} ({} of {n} rows of this column are outside){hint}",
                    i + 1,
                    bad.len()
                ),
            });
        }
        Ok(())
    }
}

impl MeasurementTable {
    /// Rows with at least one joint outside its allowed range.
    fn rows_outside(&self, limits: &[JointLimits]) -> usize {
        let ranges: Vec<(f64, f64)> = self.joint_units.iter().zip(limits).map(|(u, l)| allowed(l, u.kind())).collect();
        self.set.rows.iter().filter(|r| r.q.iter().zip(&ranges).any(|(v, (lo, hi))| !(*v >= *lo && *v <= *hi))).count()
    }
}

/// The number of distinct joint configurations among `rows` (configurations closer than
/// [`SAME_POSE_SI`] in every joint count once): repeated rows of one pose add no information
/// about the kinematics.
pub fn distinct_poses<'a>(rows: impl IntoIterator<Item = &'a PoseMeasurement>) -> usize {
    let mut seen: HashSet<Vec<i64>> = HashSet::new();
    for r in rows {
        seen.insert(r.q.iter().map(|q| (q / SAME_POSE_SI).round() as i64).collect());
    }
    seen.len()
}

/// Digits after the decimal point of a number's mantissa (`-97.82e3` has 2).
fn decimals(cell: &str) -> usize {
    let mant = cell.split(['e', 'E']).next().unwrap_or("");
    mant.split_once(['.', ',']).map_or(0, |(_, f)| f.len())
}

/// A table cut in the middle of its last number. When the text does not end with a line end,
/// the last row's last cell is compared with the same column in the other rows (at least
/// [`MIN_ROWS_FOR_CUT_CHECK`] of them): fewer decimals than every other row means the file
/// stopped mid-number (an interrupted copy or download) and is an error; otherwise a cut cannot
/// be told from a complete file that lacks its final line end, and a warning is returned (the
/// writer always ends a table with a line end). A last row with too few cells is refused by the
/// field count already.
pub(crate) fn check_not_cut(text: &str, t: &Table) -> Result<Vec<String>> {
    let Some((last, others)) = t.rows.split_last() else { return Ok(Vec::new()) };
    if text.ends_with('\n') {
        return Ok(Vec::new());
    }
    let k = last.cells.len().saturating_sub(1);
    let cell = last.cells.get(k).map_or("", String::as_str);
    let min_other = others.iter().filter_map(|r| r.cells.get(k)).map(|c| decimals(c)).min().unwrap_or(0);
    if others.len() >= MIN_ROWS_FOR_CUT_CHECK && cell.parse::<f64>().is_ok() && decimals(cell) < min_other {
        return Err(DatasetError::Invalid {
            location: t.loc(last, k),
            message: format!(
                "the file ends without a line end in '{}', which has fewer decimals than every other row of this column (at least {min_other}): was the file cut short? Restore the complete file, or end the last line with a line break if the value is complete",
                cut_cell(cell)
            ),
        });
    }
    Ok(vec![format!(
        "{}: line {}: the file ends without a line end; if it was cut short, the last row's '{}' ({}) is wrong",
        t.file.display(),
        last.line,
        t.headers.get(k).map_or("", String::as_str),
        cut_cell(cell)
    )])
}

/// Distinct poses a table needs before [`unit_warnings`] judges its units by their spread.
pub const MIN_POSES_FOR_UNIT_CHECK: usize = 5;

/// The largest value (in the column's unit) below which every joint column of a `_deg` table
/// looks like radians: 2 pi plus rounding. A calibration recording whose joints all stay within
/// 6.3 degrees cannot calibrate anything; one in radians always does.
const RADIANS_UNDER_DEG: f64 = std::f64::consts::TAU + 1e-3;

/// The words every [`unit_warnings`] warning holds before the likely unit; the commands find a
/// table's unit warnings among its other warnings by them ([`unit_advice`]).
pub const UNIT_WARNING_WORDS: &str = "the values look like ";

/// The advice of a unit warning (`the values look like metres; if so, name the columns x_m,
/// y_m, z_m`), `None` for a warning of another kind: what a command's verdict repeats.
pub fn unit_advice(warning: &str) -> Option<&str> {
    warning.find(UNIT_WARNING_WORDS).map(|k| &warning[k..])
}

/// Warnings when a table's values do not fit the units its header names, in the direction the
/// joint-limit check (degrees under `_rad`) does not catch: radians under `_deg` (every joint
/// within 2 pi), metres under `_mm` (every position, and the joints of `_mm` prismatic axes,
/// within 10), millimetres under `_m` (a position 100 m or more from the device). Empty when the
/// table has fewer than [`MIN_POSES_FOR_UNIT_CHECK`] distinct poses.
pub fn unit_warnings(table: &MeasurementTable) -> Vec<String> {
    let rows = &table.set.rows;
    let mut out = Vec::new();
    if distinct_poses(rows) < MIN_POSES_FOR_UNIT_CHECK {
        return out;
    }
    let file = table.file.display();
    let span = |values: &mut dyn Iterator<Item = f64>| {
        values.fold((f64::INFINITY, f64::NEG_INFINITY, 0.0f64), |(lo, hi, a), v| (lo.min(v), hi.max(v), a.max(v.abs())))
    };
    for (unit, limit, word, fix) in
        [(JointUnit::Deg, RADIANS_UNDER_DEG, "radians", "rad"), (JointUnit::Mm, 10.0, "metres", "m")]
    {
        let cols: Vec<usize> = (0..table.joint_units.len()).filter(|&i| table.joint_units[i] == unit).collect();
        if cols.is_empty() {
            continue;
        }
        let stats: Vec<(f64, f64, f64)> =
            cols.iter().map(|&i| span(&mut rows.iter().map(|r| unit.from_si(r.q[i])))).collect();
        if stats.iter().all(|(_, _, a)| *a <= limit) && stats.iter().any(|(lo, hi, _)| hi - lo > 1e-3) {
            let names: Vec<String> = cols.iter().map(|i| format!("q{}_{}", i + 1, unit.suffix())).collect();
            out.push(format!(
                "{file}: line {}: every joint column in {} ({}) stays within +-{limit:.1}: the values look like {word}; if so, name the columns q<i>_{fix}",
                table.header_line,
                unit.suffix(),
                names.join(", ")
            ));
        }
    }
    let pos: Vec<f64> = rows.iter().flat_map(|r| [r.position_m.x, r.position_m.y, r.position_m.z]).collect();
    if table.position_units.iter().all(|u| *u == LengthUnit::Mm) {
        let (lo, hi, a) = span(&mut pos.iter().map(|v| v * 1e3));
        if a <= 10.0 && hi - lo > 1e-6 {
            out.push(format!(
                "{file}: line {}: every position (x_mm, y_mm, z_mm) lies within +-{a:.3} mm, a span no robot calibration has: the values look like metres; if so, name the columns x_m, y_m, z_m",
                table.header_line
            ));
        }
    } else if table.position_units.iter().all(|u| *u == LengthUnit::M) {
        let (_, _, a) = span(&mut pos.iter().copied());
        if a >= 100.0 {
            out.push(format!(
                "{file}: line {}: a position lies {a:.1} m from the measuring device's origin: the values look like millimetres; if so, name the columns x_mm, y_mm, z_mm",
                table.header_line
            ));
        }
    }
    out
}

/// Rows needed before [`check_not_cut`] judges the last row by the others.
pub const MIN_ROWS_FOR_CUT_CHECK: usize = 5;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::import::parse_measurements;

    fn table(rows: &[[f64; 2]], unit: &str, end: &str) -> String {
        let mut s = format!("pose_id,q1_{unit},q2_{unit},x_mm,y_mm,z_mm\n");
        for (k, r) in rows.iter().enumerate() {
            s.push_str(&format!("{k},{},{},1.250,2.500,{:.3}\n", r[0], r[1], 3.0 + k as f64));
        }
        s.pop();
        s.push_str(end);
        s
    }

    #[test]
    fn degrees_under_a_rad_header_are_refused_with_the_unit() {
        let limits = [JointLimits { lower: -3.2, upper: 3.2 }; 2];
        let rows: Vec<[f64; 2]> = (0..10).map(|k| [0.1 * k as f64, -0.2]).collect();
        let t = parse_measurements(&table(&rows, "rad", "\n"), "t.csv").unwrap();
        t.check_joint_values(&limits, "m").unwrap();
        // Every row in degrees.
        let deg: Vec<[f64; 2]> = rows.iter().map(|r| [r[0].to_degrees() + 20.0, r[1].to_degrees()]).collect();
        let t = parse_measurements(&table(&deg, "rad", "\n"), "t.csv").unwrap();
        let e = t.check_joint_values(&limits, "m").unwrap_err().to_string();
        assert!(e.contains("line 2, column 'q1_rad'") && e.contains("10 of 10 rows") && e.contains("q1_deg"), "{e}");
        // Half the rows in degrees.
        let mut half = rows.clone();
        for r in half.iter_mut().skip(5) {
            r[1] = r[1].to_degrees() * 100.0;
        }
        let t = parse_measurements(&table(&half, "rad", "\n"), "t.csv").unwrap();
        let e = t.check_joint_values(&limits, "m").unwrap_err().to_string();
        assert!(e.contains("line 7, column 'q2_rad'") && e.contains("5 of 10 rows"), "{e}");
        // Far outside the limits in the right unit: no unit suggested.
        let far: Vec<[f64; 2]> = rows.iter().map(|r| [r[0], 1e308]).collect();
        let e = parse_measurements(&table(&far, "rad", "\n"), "t.csv")
            .and_then(|t| t.check_joint_values(&limits, "m"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("q2_rad") && !e.contains("q2_deg"), "{e}");
    }

    #[test]
    fn a_table_cut_in_its_last_number_is_refused() {
        let rows: Vec<[f64; 2]> = (0..10).map(|k| [0.1 * k as f64, -0.2]).collect();
        let full = table(&rows, "rad", "");
        let t = parse_measurements(&full, "t.csv").unwrap();
        assert!(t.warnings.len() == 1 && t.warnings[0].contains("without a line end"), "{:?}", t.warnings);
        let cut = &full[..full.len() - 2];
        let e = parse_measurements(cut, "t.csv").unwrap_err().to_string();
        assert!(e.contains("line 11, column 'z_mm'") && e.contains("cut short"), "{e}");
        let t = parse_measurements(&format!("{cut}\n"), "t.csv").unwrap();
        assert!(t.warnings.is_empty(), "a line end says the value is complete");
    }

    #[test]
    fn repeated_poses_count_once_and_long_cells_are_cut() {
        let rows: Vec<[f64; 2]> = vec![[0.5, 0.25]; 200];
        let t = parse_measurements(&table(&rows, "rad", "\n"), "t.csv").unwrap();
        assert_eq!(distinct_poses(&t.set.rows), 1);
        let long = "1".repeat(50_000_000);
        let c = cut_cell(&long);
        assert!(c.len() < 100 && c.ends_with("(50000000 characters)"), "{c}");
        assert_eq!(cut_cell("12.5"), "12.5");
    }

    /// A six-joint table of `n` poses written with the given units; joints in radians times
    /// `q_factor`, positions in metres times `p_factor`.
    fn unit_table(ju: &str, pu: &str, q_factor: f64, p_factor: f64) -> String {
        let mut s = format!("pose_id,q1_{ju},q2_{ju},q3_{ju},q4_{ju},q5_{ju},q6_{ju},x_{pu},y_{pu},z_{pu}\n");
        for k in 0..12 {
            let q: Vec<String> =
                (0..6).map(|j| format!("{:.6}", q_factor * (0.1 * k as f64 - 0.5 + 0.2 * j as f64))).collect();
            let p = [0.4 + 0.05 * k as f64, -0.3 + 0.02 * k as f64, 0.6 - 0.01 * k as f64];
            s.push_str(&format!(
                "p{k},{},{:.6},{:.6},{:.6}\n",
                q.join(","),
                p[0] * p_factor,
                p[1] * p_factor,
                p[2] * p_factor
            ));
        }
        s
    }

    #[test]
    fn units_that_do_not_fit_the_header_are_named_in_both_directions() {
        let warnings = |text: &str| parse_measurements(text, "t.csv").unwrap().warnings;
        // Right units: no warning.
        assert!(warnings(&unit_table("rad", "m", 1.0, 1.0)).is_empty());
        assert!(warnings(&unit_table("deg", "mm", 1f64.to_degrees(), 1e3)).is_empty());
        // Radians under `_deg`.
        let w = warnings(&unit_table("deg", "mm", 1.0, 1e3));
        assert!(w.len() == 1 && w[0].contains("look like radians") && w[0].contains("q<i>_rad"), "{w:?}");
        // Metres under `_mm`.
        let w = warnings(&unit_table("rad", "mm", 1.0, 1.0));
        assert!(w.len() == 1 && w[0].contains("look like metres") && w[0].contains("x_m, y_m, z_m"), "{w:?}");
        // Millimetres under `_m`.
        let w = warnings(&unit_table("rad", "m", 1.0, 1e3));
        assert!(w.len() == 1 && w[0].contains("look like millimetres"), "{w:?}");
    }

    #[test]
    fn a_european_spreadsheet_and_classic_mac_line_ends_are_read_or_named() {
        let csv = unit_table("rad", "m", 1.0, 1.0);
        // `;` between fields, decimal commas: the header is one column.
        let german = csv.replace(',', ";").replace('.', ",");
        let e = parse_measurements(&german, "t.csv").unwrap_err().to_string();
        assert!(e.contains("t.csv") && e.contains("separated by ';'") && e.contains("decimal"), "{e}");
        // Tabs.
        let e = parse_measurements(&csv.replace(',', "\t"), "t.csv").unwrap_err().to_string();
        assert!(e.contains("separated by tabs"), "{e}");
        // CR alone ends a line.
        let mac = parse_measurements(&csv.replace('\n', "\r"), "t.csv").unwrap();
        assert_eq!(mac.set.rows.len(), 12);
        assert_eq!(mac.set.rows[3].source_line, Some(5));
    }
}
