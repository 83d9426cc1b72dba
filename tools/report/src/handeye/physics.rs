//! The presentation of the chain's physics selection (`handeye`'s `physics` part): one line on
//! the terminal and an HTML section with every candidate and the accepted effects.

use ferrocal_calib::handeye::physics::ChainPhysicsReport;
use ferrocal_calib::handeye::{HandEyeResult, TargetForm};

use crate::report::Section;

/// The selection in one line: what was accepted (with values), or that nothing was, and the
/// cross-validated held-out chain RMS over the training images.
pub fn physics_line(p: &ChainPhysicsReport) -> String {
    if let Some(why) = &p.declined {
        return format!("target and lens physics: not tried ({why})");
    }
    let chosen = if p.findings.is_empty() {
        "none supported: the target is taken flat and printed to one scale, the lens model as given".to_string()
    } else {
        p.findings.iter().map(|f| f.effect.as_str()).collect::<Vec<_>>().join(", ")
    };
    let lenses = if p.rig_lenses.is_empty() {
        String::new()
    } else {
        let names: Vec<String> = p.rig_lenses.iter().enumerate().map(|(k, l)| format!("cam{k} {}", l.name())).collect();
        format!(" (lens models: {})", names.join(", "))
    };
    format!(
        "target and lens physics (decided on {} training images, {} folds): {chosen}{lenses}; cross-validated chain RMS {:.4} -> {:.4} px",
        p.n_train, p.folds, p.nominal_cv_rms_px, p.chosen_cv_rms_px
    )
}

/// The HTML section: the decision, the accepted effects in words and every candidate of every
/// step, with the fitted form's values and standard deviations.
pub fn physics_section(p: &ChainPhysicsReport, r: &HandEyeResult) -> Section {
    physics_section_with(p, r.target_form.as_ref())
}

/// [`physics_section`] with the target's form given (a rig's: pooled over its cameras).
pub fn physics_section_with(p: &ChainPhysicsReport, form: Option<&TargetForm>) -> Section {
    let mut s = Section::new("physics", "Target and lens physics in the chain (decided on the training images)");
    s.text(
        "Each candidate (the target's bending, its x-against-y print scale, another lens model) is kept only when \
         the whole hand-eye method with it predicts held-out training images better (K folds over the training \
         images; sign test and t test, corrected for the candidates). The recording's test images take no part.",
    );
    s.text(physics_line(p));
    for f in &p.findings {
        s.text(f.statement.clone());
    }
    let rows: Vec<Vec<String>> = p
        .candidates
        .iter()
        .enumerate()
        .flat_map(|(k, step)| {
            step.iter().map(move |c| {
                vec![
                    (k + 1).to_string(),
                    c.candidate.clone(),
                    format!("{:.4}", c.heldout_rms_px),
                    format!("{:.2e}", c.p_value),
                    c.verdict.clone(),
                ]
            })
        })
        .collect();
    s.table(
        "Candidates per step (cross-validated held-out chain RMS over the training images, px)",
        &["step", "candidate", "held-out RMS (px)", "p (corrected)", "verdict"],
        rows,
    );
    if let Some(form) = form {
        let d = &form.deformation;
        if let (true, Some(std)) = (d.shape_free, form.shape_std_m) {
            s.text(format!(
                "Fitted bending (sags at the target's edge, {:.0} mm from its centre): bowl {:.3} +- {:.3} mm, saddle {:.3} +- {:.3} mm, twist {:.3} +- {:.3} mm (1 sigma).",
                d.half_m * 1e3,
                d.shape_m[0] * 1e3,
                std[0] * 1e3,
                d.shape_m[1] * 1e3,
                std[1] * 1e3,
                d.shape_m[2] * 1e3,
                std[2] * 1e3
            ));
        }
        if let (true, Some(std)) = (d.scale_free, form.scale_x_std) {
            s.text(format!(
                "Fitted print scale of x against y: {:.0} +- {:.0} ppm (1 sigma).",
                d.scale[0] * 1e6,
                std * 1e6
            ));
        }
    }
    s
}
