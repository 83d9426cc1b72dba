//! The force-sensor diagnosis's cross-validation of a sensor model.

use super::*;

/// Per pose: held-out squared force error (each pose held out once), and the held-out residual
/// per pose and sensor, of `model` alone or, with `crosstalk`, of the model plus cross-talk (the
/// same folds).
pub(super) fn cross_validate(
    reg: &SensorRegressor,
    model: SensorModel,
    poses: &[Pose],
    y: &DVector<f64>,
    folds: usize,
    crosstalk: bool,
) -> Result<(Vec<f64>, DMatrix<f64>)> {
    let a = regressor(reg, model, poses)?;
    if crosstalk {
        let load = load_columns(model);
        return fold_residuals(poses.len(), folds, y, |train, test| {
            let fitted = force_crosstalk::fit(&a, y, &load, train);
            Ok(force_crosstalk::predict(&a, &load, &fitted, test))
        });
    }
    fold_residuals(poses.len(), folds, y, |train, test| {
        let fitted =
            fit(&rows_of(&a, train), &vec_of(y, train), &model.names(), &Weighting::Unit, &LinearOptions::default())?;
        Ok(fitted.predict(&rows_of(&a, test))?)
    })
}

/// The K-fold loop of the cross-validations: pose `i` is in fold `i % K`; `predict(train, test)`
/// gives the six forces of every test pose (in `test`'s order). Per pose: the held-out squared
/// force error and the residual per sensor.
pub(super) fn fold_residuals(
    n: usize,
    folds: usize,
    y: &DVector<f64>,
    mut predict: impl FnMut(&[usize], &[usize]) -> Result<DVector<f64>>,
) -> Result<(Vec<f64>, DMatrix<f64>)> {
    let k = folds.clamp(2, n);
    let mut sse = vec![0.0; n];
    let mut res = DMatrix::zeros(n, 6);
    for f in 0..k {
        let train: Vec<usize> = (0..n).filter(|i| i % k != f).collect();
        let test: Vec<usize> = (0..n).filter(|i| i % k == f).collect();
        let pred = predict(&train, &test)?;
        for (t, &i) in test.iter().enumerate() {
            for s in 0..6 {
                let r = y[6 * i + s] - pred[6 * t + s];
                sse[i] += r * r;
                res[(i, s)] = r;
            }
        }
    }
    Ok((sse, res))
}
