//! Training and held-out rows.

use crate::measurement::PoseMeasurement;

/// Splits rows into training and held-out sets: by the `split` column when any row has one,
/// else every second row held out (the source's choice) when `holdout_every_second`.
pub fn split_rows(
    rows: &[PoseMeasurement],
    holdout_every_second: bool,
) -> (Vec<&PoseMeasurement>, Vec<&PoseMeasurement>) {
    if rows.iter().any(|r| r.split.is_some()) {
        let train = rows.iter().filter(|r| r.split != Some(crate::measurement::Split::Test)).collect();
        let test = rows.iter().filter(|r| r.split == Some(crate::measurement::Split::Test)).collect();
        return (train, test);
    }
    if holdout_every_second {
        let train = rows.iter().step_by(2).collect();
        let test = rows.iter().skip(1).step_by(2).collect();
        (train, test)
    } else {
        (rows.iter().collect(), Vec::new())
    }
}
