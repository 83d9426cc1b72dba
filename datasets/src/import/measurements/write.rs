//! Writing measurement tables: the reader's format, numbers that read back bit for bit, and
//! nothing written for a set the reader would reject.

use super::*;

/// Writes a measurement table to `path` (atomically: a reader never sees half a table).
pub fn write_measurements(path: impl AsRef<Path>, set: &MeasurementSet, opts: &WriteOptions) -> Result<()> {
    let path = path.as_ref();
    let text = measurements_to_string(set, opts)?;
    crate::handeye::poses::write_atomic(path, text.as_bytes(), &[])
}

/// The measurement table of `set` as text. Fails (without writing anything) on a set the reader
/// would reject: inconsistent joint counts, duplicate or blank ids, non-finite values.
pub fn measurements_to_string(set: &MeasurementSet, opts: &WriteOptions) -> Result<String> {
    let n = opts.joint_units.len();
    if n == 0 {
        return Err(DatasetError::Input("a measurement table needs at least one joint column".into()));
    }
    let mut ids = BTreeSet::new();
    let mut meta_keys = BTreeSet::new();
    for (i, r) in set.rows.iter().enumerate() {
        let who = || format!("{}: row {} (pose_id '{}')", set.source, i + 1, r.pose_id);
        if r.q.len() != n {
            return Err(DatasetError::Input(format!(
                "{}: has {} joint values, the table {} joint columns",
                who(),
                r.q.len(),
                n
            )));
        }
        if r.pose_id.is_empty() || r.pose_id.trim() != r.pose_id {
            return Err(DatasetError::Input(format!(
                "{}: pose_id must be non-empty and without surrounding whitespace",
                who()
            )));
        }
        if !ids.insert(r.pose_id.as_str()) {
            return Err(DatasetError::Input(format!("{}: duplicate pose_id", who())));
        }
        let mut values: Vec<f64> = r.q.clone();
        values.extend(r.position_m.iter());
        values.extend(r.sigma_m);
        values.extend(r.t_s);
        values.extend(r.temp_c);
        values.extend(r.payload_kg);
        if let Some(o) = r.orientation {
            values.extend(o.coords.iter());
        }
        if values.iter().any(|v| !v.is_finite()) {
            return Err(DatasetError::Input(format!("{}: non-finite value", who())));
        }
        // What the reader refuses is never written.
        if r.q.iter().any(|v| v.abs() > MAX_JOINT_SI) || r.position_m.iter().any(|v| v.abs() > MAX_POSITION_M) {
            return Err(DatasetError::Input(format!(
                "{}: a joint value or position beyond plausible size (docs/reliability.md)",
                who()
            )));
        }
        if let Some(s) = r.sigma_m.filter(|s| *s < 0.0) {
            return Err(DatasetError::Input(format!("{}: negative standard deviation {s} m", who())));
        }
        if let Some(c) = &r.covariance {
            c.validate().map_err(|e| DatasetError::Input(format!("{}: covariance: {e}", who())))?;
        }
        if let Some(d) = &r.dir {
            if d.len() != n || d.iter().any(|v| !(-1..=1).contains(v)) {
                return Err(DatasetError::Input(format!(
                    "{}: dir needs {} values of 1, -1 or 0, got {:?}",
                    who(),
                    n,
                    d
                )));
            }
        }
        if opts.include_meta {
            for k in r.meta.keys() {
                if k.is_empty() || k.trim() != k || k.starts_with('#') || !matches!(classify(k), Ok(Column::Meta)) {
                    return Err(DatasetError::Input(format!(
                        "{}: metadata key '{k}' cannot be a column name (empty, padded, or a name the specification defines)",
                        who()
                    )));
                }
                meta_keys.insert(k.as_str());
            }
        }
    }
    let any = |f: &dyn Fn(&PoseMeasurement) -> bool| set.rows.iter().any(f);
    let has_quat = any(&|r| r.orientation.is_some());
    let has_sigma = any(&|r| r.sigma_m.is_some());
    let has_t = any(&|r| r.t_s.is_some());
    let has_temp = any(&|r| r.temp_c.is_some());
    let has_payload = any(&|r| r.payload_kg.is_some());
    let has_dir = any(&|r| r.dir.is_some());
    let has_split = any(&|r| r.split.is_some());
    let cov_size =
        set.rows.iter().filter_map(|r| r.covariance.as_ref()).map(|c| if c.pose().is_some() { 6 } else { 3 }).max();
    let cov_entries: Vec<(usize, usize)> =
        cov_size.map_or(Vec::new(), |n| (0..n).flat_map(|i| (i..n).map(move |j| (i, j))).collect());
    let lu = opts.length_unit.suffix();

    let mut header: Vec<String> = vec!["pose_id".into()];
    header.extend(opts.joint_units.iter().enumerate().map(|(i, u)| format!("q{}_{}", i + 1, u.suffix())));
    header.extend(["x", "y", "z"].iter().map(|a| format!("{a}_{lu}")));
    if has_quat {
        header.extend(["qw", "qx", "qy", "qz"].map(String::from));
    }
    if has_sigma {
        header.push(format!("sigma_{lu}"));
    }
    if has_t {
        header.push("t_s".into());
    }
    if has_temp {
        header.push("temp_c".into());
    }
    if has_payload {
        header.push("payload_kg".into());
    }
    if has_dir {
        header.extend((1..=n).map(|i| format!("dir{i}")));
    }
    if has_split {
        header.push("split".into());
    }
    header.extend(cov_entries.iter().map(|&(i, j)| cov_column(i, j, opts.length_unit)));
    header.extend(meta_keys.iter().map(|k| k.to_string()));

    let mut out = String::new();
    for c in &opts.comments {
        for line in c.lines() {
            let _ = writeln!(out, "# {line}");
        }
    }
    push_line(&mut out, header.iter().map(String::as_str));
    let opt = |v: Option<f64>| v.map_or(String::new(), fmt_f64);
    for r in &set.rows {
        let mut cells: Vec<String> = vec![r.pose_id.clone()];
        cells.extend(r.q.iter().zip(&opts.joint_units).map(|(v, u)| fmt_f64(u.from_si(*v))));
        cells.extend(r.position_m.iter().map(|v| fmt_f64(opts.length_unit.from_m(*v))));
        if has_quat {
            match r.orientation {
                Some(o) => cells.extend([o.w, o.i, o.j, o.k].map(fmt_f64)),
                None => cells.extend(std::iter::repeat_n(String::new(), 4)),
            }
        }
        if has_sigma {
            cells.push(opt(r.sigma_m.map(|s| opts.length_unit.from_m(s))));
        }
        if has_t {
            cells.push(opt(r.t_s));
        }
        if has_temp {
            cells.push(opt(r.temp_c));
        }
        if has_payload {
            cells.push(opt(r.payload_kg));
        }
        if has_dir {
            match &r.dir {
                Some(d) => cells.extend(d.iter().map(|v| v.to_string())),
                None => cells.extend(std::iter::repeat_n(String::new(), n)),
            }
        }
        if has_split {
            cells.push(match r.split {
                Some(Split::Train) => "train".into(),
                Some(Split::Test) => "test".into(),
                None => String::new(),
            });
        }
        for &(i, j) in &cov_entries {
            let lm = opts.length_unit.from_m(1.0);
            let factor = match (i < 3, j < 3) {
                (true, true) => lm * lm,
                (true, false) => lm,
                _ => 1.0,
            };
            let v = r.covariance.as_ref().and_then(|c| match c.pose() {
                Some(si) => Some(si[(i, j)]),
                None => (j < 3).then(|| c.position_m2()[(i, j)]),
            });
            cells.push(opt(v.map(|v| v * factor)));
        }
        for k in &meta_keys {
            cells.push(r.meta.get(*k).map_or(String::new(), |v| v.trim().to_string()));
        }
        push_line(&mut out, cells.iter().map(String::as_str));
    }
    Ok(out)
}

/// Formats a finite number so that parsing it gives back the same `f64`: the shortest
/// round-trip representation, in exponent form for very large or small magnitudes.
pub(crate) fn fmt_f64(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || (1e-5..1e16).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

pub(super) fn push_line<'a>(out: &mut String, cells: impl Iterator<Item = &'a str>) {
    for (i, c) in cells.enumerate() {
        if i > 0 {
            out.push(',');
        }
        if c.contains([',', '"', '\n', '\r']) || c.starts_with('#') {
            out.push('"');
            out.push_str(&c.replace('"', "\"\""));
            out.push('"');
        } else {
            out.push_str(c);
        }
    }
    out.push('\n');
}
