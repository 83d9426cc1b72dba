//! Link physics: the end compliance of a straight cantilever beam, and the sparsity template it
//! implies (step M2 of the model reduction).
//!
//! A beam of length `L` along axis `a` of its end frame, clamped at its start and loaded at its
//! end, with `(b, c)` the other two axes in cyclic order (`x -> y -> z -> x`), deflects as
//!
//! | entry | value |
//! | --- | --- |
//! | `k_aa` (axial) | `L / EA` |
//! | `k_bb` | `L^3 / (3 EI_c)` |
//! | `k_cc` | `L^3 / (3 EI_b)` |
//! | `k_(a+3)(a+3)` (torsion) | `L / GJ` |
//! | `k_(b+3)(b+3)` | `L / EI_b` |
//! | `k_(c+3)(c+3)` | `L / EI_c` |
//! | `k_b(c+3) = k_(c+3)b` | `+L^2 / (2 EI_c)` |
//! | `k_c(b+3) = k_(b+3)c` | `-L^2 / (2 EI_b)` |
//!
//! (`EI_b`: bending stiffness for rotation about axis `b`.) For a beam along x these are the
//! diagonal plus `k26 = k62 > 0` and `k35 = k53 < 0`, the pattern of Klimchik's Orthoglide link.
//! Every other entry of a beam's compliance matrix is zero: that is the template.

use nalgebra::Matrix6;
use serde::{Deserialize, Serialize};

use crate::stiffness::error::{Result, StiffnessError};

/// Section properties of a straight, uniform beam.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BeamStiffness {
    /// Length from the clamped start to the loaded end.
    pub length_m: f64,
    /// Axial stiffness `E A`.
    pub axial_n: f64,
    /// Bending stiffness `E I` for rotation about the first axis after the beam axis in cyclic
    /// order (about y for a beam along x).
    pub bending_1_nm2: f64,
    /// Bending stiffness for rotation about the second axis (about z for a beam along x).
    pub bending_2_nm2: f64,
    /// Torsional stiffness `G J`.
    pub torsion_nm2: f64,
}

impl BeamStiffness {
    /// Checks that every property is finite and positive.
    pub fn validate(&self, what: &str) -> Result<()> {
        for (name, v) in [
            ("length_m", self.length_m),
            ("axial_n", self.axial_n),
            ("bending_1_nm2", self.bending_1_nm2),
            ("bending_2_nm2", self.bending_2_nm2),
            ("torsion_nm2", self.torsion_nm2),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(StiffnessError::BadCompliance {
                    what: what.to_string(),
                    reason: format!("beam property {name} = {v} must be finite and positive"),
                });
            }
        }
        Ok(())
    }

    /// The end compliance (SI: m/N, rad/(N m), 1/N) in the end frame, beam along `axis`
    /// (0 = x, 1 = y, 2 = z).
    pub fn compliance(&self, axis: usize, what: &str) -> Result<Matrix6<f64>> {
        self.validate(what)?;
        if axis > 2 {
            return Err(StiffnessError::Structure(format!("{what}: beam axis {axis} is not 0, 1 or 2")));
        }
        let (a, b, c) = (axis, (axis + 1) % 3, (axis + 2) % 3);
        let l = self.length_m;
        let (ei_b, ei_c) = (self.bending_1_nm2, self.bending_2_nm2);
        let mut k = Matrix6::zeros();
        k[(a, a)] = l / self.axial_n;
        k[(b, b)] = l.powi(3) / (3.0 * ei_c);
        k[(c, c)] = l.powi(3) / (3.0 * ei_b);
        k[(a + 3, a + 3)] = l / self.torsion_nm2;
        k[(b + 3, b + 3)] = l / ei_b;
        k[(c + 3, c + 3)] = l / ei_c;
        k[(b, c + 3)] = l * l / (2.0 * ei_c);
        k[(c + 3, b)] = k[(b, c + 3)];
        k[(c, b + 3)] = -l * l / (2.0 * ei_b);
        k[(b + 3, c)] = k[(c, b + 3)];
        Ok(k)
    }
}

/// The sparsity template of a beam along `axis` (0, 1, 2): `true` where a beam's compliance
/// matrix may be non-zero. `None` (no beam axis known): every entry.
pub fn beam_template(axis: Option<usize>) -> [[bool; 6]; 6] {
    let Some(axis) = axis.filter(|a| *a < 3) else {
        return [[true; 6]; 6];
    };
    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut t = [[false; 6]; 6];
    for (i, row) in t.iter_mut().enumerate() {
        row[i] = true;
    }
    t[b][c + 3] = true;
    t[c + 3][b] = true;
    t[c][b + 3] = true;
    t[b + 3][c] = true;
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beam_along_x_has_the_orthoglide_pattern() {
        let b = BeamStiffness { length_m: 0.5, axial_n: 2e8, bending_1_nm2: 1e4, bending_2_nm2: 2e4, torsion_nm2: 5e3 };
        let k = b.compliance(0, "test").unwrap();
        assert!(k[(1, 5)] > 0.0 && (k[(1, 5)] - k[(5, 1)]).abs() < 1e-18);
        assert!(k[(2, 4)] < 0.0 && (k[(2, 4)] - k[(4, 2)]).abs() < 1e-18);
        let t = beam_template(Some(0));
        for i in 0..6 {
            for j in 0..6 {
                if !t[i][j] {
                    assert_eq!(k[(i, j)], 0.0, "{i}{j}");
                }
            }
        }
        assert_eq!(t.iter().flatten().filter(|v| **v).count(), 10);
        // Positive definite.
        assert!(k.symmetric_eigenvalues().iter().all(|l| *l > 0.0));
    }
}
