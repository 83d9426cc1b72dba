//! The two back ends side by side on one problem: a rigid registration (one SE(3) block, 3 rows
//! per point) and a small bundle-like problem (a global block plus many local pose blocks).

use std::sync::Arc;

use criterion::{criterion_group, criterion_main, Criterion};
use ferrocal_lsq::{Backend, Loss, Problem, Residual, Result, Se3, SolverOptions};
use nalgebra::{DMatrix, Isometry3, Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// `(T p - q) / sigma` over an SE(3) block, and optionally a global scale on `p`.
struct Scaled {
    p: Point3<f64>,
    q: Point3<f64>,
}

impl Residual for Scaled {
    fn n_residuals(&self) -> usize {
        3
    }
    fn evaluate(&self, x: &[&[f64]], out: &mut [f64], jac: Option<&mut [Option<DMatrix<f64>>]>) -> Result<()> {
        let s = x[0][0];
        let t = Se3::to_isometry(x[1]);
        let rp = t.rotation * (self.p.coords * s);
        let e = (rp + t.translation.vector - self.q.coords) / 1e-3;
        out.copy_from_slice(e.as_slice());
        if let Some(j) = jac {
            if let Some(js) = &mut j[0] {
                let d = t.rotation * self.p.coords / 1e-3;
                js.copy_from_slice(d.as_slice());
            }
            if let Some(jt) = &mut j[1] {
                let skew = rp.cross_matrix();
                for r in 0..3 {
                    jt[(r, r)] = 1e3;
                    for c in 0..3 {
                        jt[(r, 3 + c)] = -skew[(r, c)] * 1e3;
                    }
                }
            }
        }
        Ok(())
    }
}

fn problem(views: usize, points: usize, seed: u64) -> Problem {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut p = Problem::new();
    let s = p.add_euclidean("scale", vec![1.0]).unwrap();
    for v in 0..views {
        let truth = Isometry3::new(
            Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)),
            Vector3::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0)),
        );
        let start = truth * Isometry3::new(Vector3::new(0.01, -0.02, 0.01), Vector3::new(0.05, 0.02, -0.03));
        let b = p.add_block(&format!("view{v}"), Se3::from_isometry(&start).to_vec(), Arc::new(Se3)).unwrap();
        for k in 0..points {
            let pt = Point3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            let q = truth * Point3::from(pt.coords * 1.001);
            p.add_residual(&format!("v{v}p{k}"), Box::new(Scaled { p: pt, q }), &[s, b], Loss::Squared).unwrap();
        }
    }
    p
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("lsq");
    g.sample_size(10);
    for (views, points) in [(1, 200), (20, 30)] {
        for backend in [Backend::Dense, Backend::Ceres] {
            g.bench_function(format!("{views}x{points} {backend:?}"), |b| {
                b.iter(|| {
                    let mut p = problem(views, points, 1);
                    p.solve(&SolverOptions { backend, ..Default::default() }).unwrap()
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
