//! The least-squares layer on problems with known answers: manifolds, Jacobians, both back ends,
//! robust losses, covariance (dense and Schur) against Monte Carlo, and the indexes.

use std::sync::Arc;

use ferrocal_lsq::check::{check_manifold, check_residual};
use ferrocal_lsq::{
    Backend, Euclidean, Loss, LsqError, Manifold, Problem, Residual, Result, Se3, So3, SolverOptions, UnitVector3,
};
use nalgebra::{DMatrix, Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn random_pose(rng: &mut ChaCha8Rng, angle: f64) -> Isometry3<f64> {
    let axis =
        Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)).normalize();
    Isometry3::from_parts(
        Translation3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)),
        UnitQuaternion::from_scaled_axis(axis * angle),
    )
}

#[test]
fn every_manifold_passes_the_manifold_check() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for trial in 0..20 {
        let angle = if trial < 3 { std::f64::consts::PI - 1e-3 * trial as f64 } else { rng.random_range(0.0..3.0) };
        let pose = random_pose(&mut rng, angle);
        let q = pose.rotation;
        let se3 = Se3::from_isometry(&pose);
        let dir = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))
            .normalize();
        let cases: Vec<(Box<dyn Manifold>, Vec<f64>)> = vec![
            (Box::new(Euclidean { n: 3 }), vec![1.0, -2.0, 0.5]),
            (Box::new(So3), vec![q.w, q.i, q.j, q.k]),
            (Box::new(Se3), se3.to_vec()),
            (Box::new(UnitVector3), dir.as_slice().to_vec()),
        ];
        for (m, x) in cases {
            let nt = m.tangent_size();
            let deltas: Vec<Vec<f64>> =
                (0..5).map(|_| (0..nt).map(|_| rng.random_range(-0.3..0.3)).collect()).collect();
            let err = check_manifold(m.as_ref(), &x, &deltas).unwrap();
            assert!(err < 1e-8, "{} at {x:?}: {err:.2e}", m.name());
        }
    }
}

/// `r_i = (T p_i - q_i) / sigma` over one SE(3) block.
struct PointToPoint {
    p: Point3<f64>,
    q: Point3<f64>,
    sigma_m: f64,
}

impl Residual for PointToPoint {
    fn n_residuals(&self) -> usize {
        3
    }
    fn evaluate(&self, params: &[&[f64]], out: &mut [f64], jac: Option<&mut [Option<DMatrix<f64>>]>) -> Result<()> {
        let t = Se3::to_isometry(params[0]);
        let rp = t.rotation * self.p.coords;
        let e = (rp + t.translation.vector - self.q.coords) / self.sigma_m;
        out.copy_from_slice(e.as_slice());
        if let Some(j) = jac {
            if let Some(j0) = &mut j[0] {
                let skew = rp.cross_matrix();
                for r in 0..3 {
                    j0[(r, r)] = 1.0 / self.sigma_m;
                    for c in 0..3 {
                        j0[(r, 3 + c)] = -skew[(r, c)] / self.sigma_m;
                    }
                }
            }
        }
        Ok(())
    }
    fn row_names(&self) -> Vec<String> {
        ["x_m", "y_m", "z_m"].map(String::from).to_vec()
    }
}

/// `r = (s * (a . p) - d) / sigma`: a length `d` measured along an axis `a` (unit vector) with a
/// scale `s` (Euclidean, global) — exercises two manifolds in one block.
struct Projection {
    p: Vector3<f64>,
    d: f64,
    sigma: f64,
}

impl Residual for Projection {
    fn n_residuals(&self) -> usize {
        1
    }
    fn evaluate(&self, params: &[&[f64]], out: &mut [f64], jac: Option<&mut [Option<DMatrix<f64>>]>) -> Result<()> {
        let s = params[0][0];
        let a = Vector3::new(params[1][0], params[1][1], params[1][2]);
        out[0] = (s * a.dot(&self.p) - self.d) / self.sigma;
        if let Some(j) = jac {
            if let Some(js) = &mut j[0] {
                js[(0, 0)] = a.dot(&self.p) / self.sigma;
            }
            if let Some(ja) = &mut j[1] {
                let b = UnitVector3::basis(params[1]);
                let g = b.transpose() * self.p * (s / self.sigma);
                ja[(0, 0)] = g[0];
                ja[(0, 1)] = g[1];
            }
        }
        Ok(())
    }
}

fn registration(rng: &mut ChaCha8Rng, truth: &Isometry3<f64>, n: usize, sigma_m: f64) -> Vec<PointToPoint> {
    let noise = Normal::new(0.0, sigma_m).unwrap();
    (0..n)
        .map(|_| {
            let p = Point3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            let q = truth * p + Vector3::new(noise.sample(rng), noise.sample(rng), noise.sample(rng));
            PointToPoint { p, q, sigma_m }
        })
        .collect()
}

#[test]
fn residuals_pass_the_gradient_checker() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let pose = random_pose(&mut rng, 2.5);
    let x = Se3::from_isometry(&pose);
    for r in registration(&mut rng, &pose, 5, 1e-3) {
        let rep = check_residual(&r, &[&x], &[Arc::new(Se3)], &[vec![1.0; 6]], 1e-6).unwrap();
        rep.assert_below(1e-6, "point-to-point").unwrap();
    }
    let a = Vector3::new(0.3, -0.5, 0.8).normalize();
    let r = Projection { p: Vector3::new(0.2, 1.1, -0.4), d: 0.3, sigma: 1e-3 };
    let rep = check_residual(
        &r,
        &[&[1.02], a.as_slice()],
        &[Arc::new(Euclidean { n: 1 }), Arc::new(UnitVector3)],
        &[vec![1.0], vec![1.0; 2]],
        1e-6,
    )
    .unwrap();
    rep.assert_below(1e-6, "projection").unwrap();
    // A wrong Jacobian is caught.
    struct Wrong;
    impl Residual for Wrong {
        fn n_residuals(&self) -> usize {
            1
        }
        fn evaluate(&self, p: &[&[f64]], out: &mut [f64], jac: Option<&mut [Option<DMatrix<f64>>]>) -> Result<()> {
            out[0] = p[0][0] * p[0][0];
            if let Some(j) = jac {
                if let Some(j0) = &mut j[0] {
                    j0[(0, 0)] = p[0][0]; // should be 2 x
                }
            }
            Ok(())
        }
    }
    let rep = check_residual(&Wrong, &[&[3.0]], &[Arc::new(Euclidean { n: 1 })], &[vec![1.0]], 1e-6).unwrap();
    assert!(rep.assert_below(1e-6, "wrong").is_err());
}

fn registration_problem(
    rows: Vec<PointToPoint>,
    start: &Isometry3<f64>,
    loss: Loss,
) -> (Problem, ferrocal_lsq::BlockId) {
    let mut p = Problem::new();
    let id = p.add_block("t_world_target", Se3::from_isometry(start).to_vec(), Arc::new(Se3)).unwrap();
    p.set_scales(id, vec![0.1, 0.1, 0.1, 0.1, 0.1, 0.1]).unwrap();
    for (k, r) in rows.into_iter().enumerate() {
        p.add_residual(&format!("point{k}"), Box::new(r), &[id], loss).unwrap();
    }
    (p, id)
}

#[test]
fn both_back_ends_find_the_same_registration_and_its_covariance_matches_monte_carlo() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let truth = random_pose(&mut rng, 2.9);
    let start = truth * random_pose(&mut rng, 0.4);
    let sigma_m = 1e-3;
    let mut errors = Vec::new();
    let mut predicted = None;
    for trial in 0..60 {
        let rows = registration(&mut rng, &truth, 30, sigma_m);
        let rows2: Vec<PointToPoint> = rows.iter().map(|r| PointToPoint { ..*r }).collect();
        let (mut dense, id) = registration_problem(rows, &start, Loss::Squared);
        let sol = dense.solve(&SolverOptions { backend: Backend::Dense, ..Default::default() }).unwrap();
        assert!(sol.summary.converged, "{:?}", sol.summary);
        let est = Se3::to_isometry(&dense.block(id).values);
        if trial < 5 {
            let (mut ceres, cid) = registration_problem(rows2, &start, Loss::Squared);
            let sol = ceres.solve(&SolverOptions { backend: Backend::Ceres, ..Default::default() }).unwrap();
            assert!(sol.summary.converged, "{:?}", sol.summary);
            let other = Se3::to_isometry(&ceres.block(cid).values);
            assert!((other.translation.vector - est.translation.vector).norm() < 1e-9);
            let angle = other.rotation.angle_to(&est.rotation);
            assert!(angle < 1e-8, "dense and Ceres differ by {angle:.2e} rad ({:?})", sol.summary);
        }
        if trial == 0 {
            let cov = dense.covariance().unwrap();
            assert!((cov.s0 - 1.0).abs() < 0.35, "s0 {}", cov.s0);
            predicted = Some(cov.matrix / (cov.s0 * cov.s0));
            assert_eq!(cov.index.names()[3], "t_world_target.rx");
        }
        let mut d = vec![0.0; 6];
        Se3.minus(&Se3::from_isometry(&est), &Se3::from_isometry(&truth), &mut d);
        errors.push(d);
    }
    let predicted = predicted.unwrap();
    for i in 0..6 {
        let sd = (errors.iter().map(|e| e[i] * e[i]).sum::<f64>() / errors.len() as f64).sqrt();
        let ratio = sd / predicted[(i, i)].sqrt();
        assert!((0.7..1.35).contains(&ratio), "coordinate {i}: scatter / predicted = {ratio:.3}");
    }
}

#[test]
fn a_robust_loss_ignores_outliers_on_both_back_ends() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let truth = random_pose(&mut rng, 1.0);
    for backend in [Backend::Dense, Backend::Ceres] {
        let mut rows = registration(&mut rng, &truth, 40, 1e-3);
        for r in rows.iter_mut().take(4) {
            r.q += Vector3::new(0.05, -0.08, 0.03);
        }
        let (mut p, id) = registration_problem(rows, &truth, Loss::Cauchy { delta: 3.0 });
        let sol = p.solve(&SolverOptions { backend, ..Default::default() }).unwrap();
        let est = Se3::to_isometry(&p.block(id).values);
        assert!((est.translation.vector - truth.translation.vector).norm() < 1e-3, "{backend:?}");
        assert!(sol.summary.downweighted_blocks >= 4, "{backend:?}: {:?}", sol.summary);
    }
}

#[test]
fn schur_covariance_equals_the_global_corner_of_the_dense_one() {
    // A global scale and axis, and per-view offsets (local blocks): d_ik = s (a . p_ik) + o_k.
    struct WithOffset(Projection);
    impl Residual for WithOffset {
        fn n_residuals(&self) -> usize {
            1
        }
        fn evaluate(&self, p: &[&[f64]], out: &mut [f64], jac: Option<&mut [Option<DMatrix<f64>>]>) -> Result<()> {
            let mut sub: Option<Vec<Option<DMatrix<f64>>>> = jac.as_ref().map(|j| vec![j[0].clone(), j[1].clone()]);
            self.0.evaluate(&p[..2], out, sub.as_deref_mut())?;
            out[0] += p[2][0] / self.0.sigma;
            if let (Some(j), Some(sub)) = (jac, sub) {
                j[0] = sub[0].clone();
                j[1] = sub[1].clone();
                if let Some(j2) = &mut j[2] {
                    j2[(0, 0)] = 1.0 / self.0.sigma;
                }
            }
            Ok(())
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let mut p = Problem::new();
    let s = p.add_euclidean("scale", vec![1.01]).unwrap();
    let a = p
        .add_block("axis", Vector3::new(0.2, 0.1, 1.0).normalize().as_slice().to_vec(), Arc::new(UnitVector3))
        .unwrap();
    for k in 0..8 {
        let o = p.add_euclidean(&format!("offset{k}"), vec![0.01 * k as f64]).unwrap();
        for i in 0..6 {
            let v = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(0.5..1.5));
            let r = WithOffset(Projection { p: v, d: rng.random_range(0.0..1.0), sigma: 0.01 });
            p.add_residual(&format!("v{k}.{i}"), Box::new(r), &[s, a, o], Loss::Squared).unwrap();
        }
    }
    let dense = p.covariance().unwrap();
    let schur = p.schur_covariance(&[s, a]).unwrap();
    assert_eq!(schur.matrix.nrows(), 3);
    for i in 0..3 {
        for j in 0..3 {
            let (x, y) = (schur.matrix[(i, j)], dense.matrix[(i, j)]);
            assert!((x - y).abs() <= 1e-9 * y.abs().max(dense.matrix[(i, i)]), "({i},{j}): {x} vs {y}");
        }
    }
    // Blocks that share a residual are refused as locals.
    assert!(p.schur_covariance(&[s]).is_err());
}

#[test]
fn bad_set_up_is_refused_with_names() {
    let mut p = Problem::new();
    let e = p.add_block("rot", vec![1.0, 0.0, 0.0, 0.5], Arc::new(So3)).unwrap_err();
    assert!(e.to_string().contains("'rot'"), "{e}");
    let id = p.add_euclidean("x", vec![0.0]).unwrap();
    assert!(matches!(p.add_euclidean("x", vec![1.0]), Err(LsqError::Setup(_))));
    assert!(p.set_scales(id, vec![0.0]).is_err());
    assert!(SolverOptions { max_iterations: 0, ..Default::default() }.validate().is_err());
    assert!(SolverOptions { cost_tolerance: f64::NAN, ..Default::default() }.validate().is_err());
    assert!(p.solve(&SolverOptions::default()).is_err(), "no residuals");
}
