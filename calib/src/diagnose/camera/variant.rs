//! What the camera and the stereo families share: a model variant of `N` cameras, what a
//! candidate adds to the current variant, the candidates of a step, their description, the
//! screening against the current variant's held-out errors, the accepted effect's parameters
//! and the plausibility of its size.

use std::collections::BTreeMap;

use ferrocal_vision::calib::TargetShape;
use ferrocal_vision::camera::{Distortion, DistortionKind};

use super::super::engine::{Baseline, Describe, Screened};
use super::CameraDiagnoseOptions;

/// A model variant of `N` cameras: each camera's lens model, whether the target may bend (one
/// target for all cameras), whether its print may be scaled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::diagnose) struct Variant<const N: usize> {
    /// Each camera's lens model (`vision::camera`'s list).
    pub(in crate::diagnose) lens: [DistortionKind; N],
    pub(in crate::diagnose) bent: bool,
    pub(in crate::diagnose) scaled: bool,
}

/// Which effect a variant adds to the current one (a lens model: of which camera).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::diagnose) enum Added {
    Lens(usize),
    Shape,
    PrintScale,
}

impl<const N: usize> Variant<N> {
    /// The default model: 5-coefficient Brown for every camera, a flat and nominally printed
    /// target.
    pub(in crate::diagnose) const NOMINAL: Self =
        Variant { lens: [DistortionKind::Brown5; N], bent: false, scaled: false };

    /// What `self` adds to `current` (a lens model: of the last camera whose model differs).
    pub(in crate::diagnose) fn added_to(self, current: Self) -> Added {
        if self.bent && !current.bent {
            Added::Shape
        } else if self.scaled && !current.scaled {
            Added::PrintScale
        } else {
            Added::Lens((0..N).rev().find(|&c| self.lens[c] != current.lens[c]).unwrap_or(0))
        }
    }

    /// The candidates from `self`: per camera (labelled `lens_label(camera, model)`) the
    /// rational and the Kannala-Brandt lens models in place of a 5-coefficient one, then the
    /// target's bending and print scale (`target_note` closing their labels' brackets).
    pub(in crate::diagnose) fn candidates(
        self,
        lens_label: impl Fn(usize, &str) -> String,
        target_note: &str,
    ) -> Vec<(String, Self)> {
        let mut cands = Vec::new();
        for c in 0..N {
            if self.lens[c] == DistortionKind::Brown5 {
                for (lens, what) in [
                    (DistortionKind::Rational8, "rational radial k4..k6"),
                    (DistortionKind::KannalaBrandt, "Kannala-Brandt fisheye"),
                ] {
                    let mut v = self;
                    v.lens[c] = lens;
                    cands.push((lens_label(c, what), v));
                }
            }
        }
        if !self.bent {
            cands.push((
                format!("target_nonflatness (bowl, saddle, twist{target_note})"),
                Variant { bent: true, ..self },
            ));
        }
        if !self.scaled {
            cands.push((
                format!("target_print_scale (x spacing against y{target_note})"),
                Variant { scaled: true, ..self },
            ));
        }
        cands
    }

    /// The engine's description of the candidate `label` leading from `current` to `self`.
    pub(in crate::diagnose) fn describe(self, current: Self, label: &str) -> Describe {
        let (effect, n_params) = match self.added_to(current) {
            Added::Shape => ("target_nonflatness", 3),
            Added::PrintScale => ("target_print_scale", 1),
            Added::Lens(c) if self.lens[c] == DistortionKind::KannalaBrandt => ("lens_distortion", 4),
            Added::Lens(_) => ("lens_distortion", 3),
        };
        Describe { label: label.to_string(), effect: effect.into(), joints: Vec::new(), n_params }
    }
}

/// A candidate's screening from its cross-validation `cv` (unscored when it could not be
/// fitted): per held-out unit (a view, a pair of `units`) the difference of mean squared error
/// of the current variant (`current`) and the candidate's (`errors(cv)`, each a sum of squares
/// and a count), unscored when the candidate cannot place some unit.
pub(in crate::diagnose) fn screened<D>(
    cv: crate::error::Result<D>,
    errors: impl Fn(&D) -> &[(f64, usize)],
    current: &[(f64, usize)],
    units: &str,
) -> Screened<D> {
    let cv = match cv {
        Ok(cv) => cv,
        Err(e) => return Screened::Unscored { heldout: f64::NAN, why: format!("could not be fitted: {e}") },
    };
    let errors = errors(&cv);
    let d: Vec<f64> = current.iter().zip(errors).map(|((a, na), (b, _))| (a - b) / (*na).max(1) as f64).collect();
    if d.iter().any(|v| !v.is_finite()) {
        return Screened::Unscored {
            heldout: f64::INFINITY,
            why: format!(
                "fails to predict some held-out {units} (their corners leave the fitted lens model's valid field)"
            ),
        };
    }
    let heldout = Baseline::of_pooled(errors).heldout;
    Screened::Scored { d, heldout, data: cv }
}

/// The parameters of the effect `kind` of a fit (target `shape`, print scale `e_x`, and `lens`
/// (camera `c`'s distortion) for a lens effect) by name, and their standard deviations taken
/// from `std` (by the fit's parameter names; a lens coefficient's there is `lens_prefix(c)`
/// and its name).
pub(in crate::diagnose) fn effect_parameters(
    kind: Added,
    (shape, e_x): (TargetShape, f64),
    lens: impl Fn(usize) -> Distortion,
    std: &BTreeMap<String, f64>,
    lens_prefix: impl Fn(usize) -> String,
) -> (BTreeMap<String, f64>, BTreeMap<String, f64>) {
    let mut values = BTreeMap::new();
    let mut stds = BTreeMap::new();
    let mut put = |name: &str, std_name: &str, v: f64| {
        values.insert(name.to_string(), v);
        if let Some(s) = std.get(std_name) {
            stds.insert(name.to_string(), *s);
        }
    };
    match kind {
        Added::Shape => {
            for (name, v) in
                ["bowl_sag_m", "saddle_sag_m", "twist_sag_m"].iter().zip([shape.bowl_m, shape.saddle_m, shape.twist_m])
            {
                put(name, name, v);
            }
        }
        Added::PrintScale => put("scale_x_minus_y", "print_scale_x", e_x),
        Added::Lens(c) => {
            let d = lens(c);
            for (name, v) in d.kind().coefficient_names().iter().zip(&d.coefficients()) {
                put(name, &format!("{}{name}", lens_prefix(c)), *v);
            }
        }
    }
    (values, stds)
}

/// Whether the effect `kind` of a fit has a plausible size (`Err`: why not): every sag of the
/// target `shape` within the options' `max_sag_m`, the print scale `e_x` within
/// `max_print_scale`, every coefficient of the lens model `lens(c)` within `max_rational`.
pub(in crate::diagnose) fn plausible_size(
    kind: Added,
    (shape, e_x): (TargetShape, f64),
    lens: impl Fn(usize) -> Distortion,
    opts: &CameraDiagnoseOptions,
) -> std::result::Result<(), String> {
    let ok = match kind {
        Added::Shape => [shape.bowl_m, shape.saddle_m, shape.twist_m].iter().all(|b| b.abs() <= opts.max_sag_m),
        Added::PrintScale => e_x.abs() <= opts.max_print_scale,
        Added::Lens(c) => lens(c).coefficients().iter().all(|v| v.abs() <= opts.max_rational),
    };
    if ok {
        Ok(())
    } else {
        Err("implausible size".into())
    }
}
