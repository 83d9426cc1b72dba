//! The subspace manifold of the joint adjustment: a vector of which only some coordinates move.

use nalgebra::DMatrix;

/// A vector of which only some coordinates move: ambient `n` values, tangent = the coordinates
/// in `free` (the others keep their values). How the frame and tool increments of the kinematic
/// selection are held where the selection fixed them.
#[derive(Clone, Debug)]
pub(super) struct Subspace {
    /// Ambient size.
    pub(super) n: usize,
    /// The coordinates that move.
    pub(super) free: Vec<usize>,
}

impl ferrocal_lsq::Manifold for Subspace {
    fn name(&self) -> &'static str {
        "subspace"
    }
    fn ambient_size(&self) -> usize {
        self.n
    }
    fn tangent_size(&self) -> usize {
        self.free.len()
    }
    fn plus(&self, x: &[f64], delta: &[f64], out: &mut [f64]) {
        out.copy_from_slice(x);
        for (k, &i) in self.free.iter().enumerate() {
            out[i] += delta[k];
        }
    }
    fn minus(&self, y: &[f64], x: &[f64], out: &mut [f64]) {
        for (k, &i) in self.free.iter().enumerate() {
            out[k] = y[i] - x[i];
        }
    }
    fn plus_jacobian(&self, _x: &[f64]) -> DMatrix<f64> {
        let mut j = DMatrix::zeros(self.n, self.free.len());
        for (k, &i) in self.free.iter().enumerate() {
            j[(i, k)] = 1.0;
        }
        j
    }
    fn contains(&self, x: &[f64]) -> bool {
        x.len() == self.n && x.iter().all(|v| v.is_finite())
    }
    fn tangent_names(&self) -> Vec<String> {
        self.free.iter().map(|i| format!("c{i}")).collect()
    }
}
