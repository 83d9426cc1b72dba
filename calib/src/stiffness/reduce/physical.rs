//! Physical plausibility of an identified compliance: the stiffnesses that must be positive, and the identification refused when the complete model is not physical.

use super::*;

/// The spring compliance matrices and joint compliances of complete values, checked: negative
/// joint compliance or diagonal entry, asymmetric pairs, a symmetric part that is not positive
/// semi-definite. Each problem comes with its owner (`joint2`, `link3`).
pub fn physical_problems(layout: &ComplianceLayout, complete: &[f64]) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for j in 0..layout.n_joints {
        if let Some(i) = layout.joint_index(j) {
            if complete[i] < 0.0 {
                out.push((format!("joint{}", j + 1), format!("joint{}.k = {:.3e} is negative", j + 1, complete[i])));
            }
        }
    }
    for (s, name) in layout.spring_names.iter().enumerate() {
        let mut k = Matrix6::zeros();
        let mut any = false;
        for r in 0..6 {
            for c in 0..6 {
                if let Some(i) = layout.spring_index(s, r, c) {
                    k[(r, c)] = complete[i];
                    any |= complete[i] != 0.0;
                }
            }
        }
        if !any {
            continue;
        }
        for r in 0..6 {
            if k[(r, r)] < 0.0 {
                out.push((name.clone(), format!("{name}.k{}{} = {:.3e} is negative", r + 1, r + 1, k[(r, r)])));
            }
        }
        let mut asym = Vec::new();
        for r in 0..6 {
            for c in r + 1..6 {
                let (a, b) = (k[(r, c)], k[(c, r)]);
                let big = a.abs().max(b.abs());
                if big > 0.0 && (a - b).abs() > 0.1 * big {
                    asym.push(format!("k{}{} = {a:.2e} vs k{}{} = {b:.2e}", r + 1, c + 1, c + 1, r + 1));
                }
            }
        }
        if !asym.is_empty() {
            let n = asym.len();
            asym.truncate(3);
            out.push((name.clone(), format!("{name} is asymmetric in {n} pair(s), e.g. {}", asym.join(", "))));
        }
        // Positive semi-definite symmetric part, normalised by the positive diagonal.
        let d: Vec<f64> = (0..6).map(|r| if k[(r, r)] > 0.0 { 1.0 / k[(r, r)].sqrt() } else { 0.0 }).collect();
        let ks = (k + k.transpose()) * 0.5;
        let kn = Matrix6::from_fn(|r, c| ks[(r, c)] * d[r] * d[c]);
        let lmin = kn.symmetric_eigenvalues().min();
        let off_rigid = (0..6).any(|r| d[r] == 0.0 && (0..6).any(|c| c != r && ks[(r, c)] != 0.0));
        if lmin < -1e-9 || off_rigid {
            out.push((
                name.clone(),
                format!("{name} is not positive definite (smallest eigenvalue of the normalised matrix {lmin:.3})"),
            ));
        }
    }
    out
}

/// Fits `param` (with `fixed` complete values for everything else) and refuses a result that
/// cannot be trusted: loads that leave a parameter without effect or coupled
/// ([`StiffnessIdError::Unexcited`]), and an estimate that is not physical
/// ([`StiffnessIdError::NotPhysical`]). Both errors list the parameters that can be trusted.
pub fn identify_checked(
    problem: &LinearProblem,
    param: &Parameterization,
    fixed: &DVector<f64>,
    settings: &ReductionSettings,
) -> Result<Fit> {
    settings.validate()?;
    let a = reduced_regressor(problem, param);
    let names = param.names();
    let id = analyze(&unit_columns(&a), &names, settings.rank_tol)?;
    if id.rank < param.len() {
        let pick = |c: ParamClass| -> Vec<String> {
            names.iter().zip(&id.classes).filter(|(_, k)| **k == c).map(|(n, _)| n.clone()).collect()
        };
        return Err(StiffnessIdError::Unexcited {
            unexcited: pick(ParamClass::NotIdentifiable),
            coupled: id.describe_groups(),
            trusted: pick(ParamClass::Identifiable),
        });
    }
    let f = fit_with_fixed(problem, param, fixed, settings.rank_tol)?;
    let complete: Vec<f64> = (param.expand(&f.values) + fixed).iter().copied().collect();
    let problems = physical_problems(&problem.layout, &complete);
    if !problems.is_empty() {
        let owners: Vec<String> = problems.iter().map(|(o, _)| format!("{o}.")).collect();
        let trusted = names
            .iter()
            .zip(&f.nu)
            .filter(|(n, nu)| **nu >= settings.nu_threshold && !owners.iter().any(|o| n.starts_with(o.as_str())))
            .map(|(n, nu)| format!("{n} (nu {nu:.1})"))
            .collect();
        return Err(StiffnessIdError::NotPhysical {
            problems: problems.into_iter().map(|(_, t)| t).collect(),
            trusted,
        });
    }
    Ok(f)
}
