//! The diagnose engine on its own, with a toy family: a straight line fitted to data whose truth
//! may hold one extra polynomial term. The candidates are the terms x^2, x^3 and x^4; the engine
//! must accept the one the truth holds and nothing else, and accept nothing when the truth is a
//! line.

use std::collections::BTreeMap;

use ferrocal_calib::diagnose::engine::{
    select, AllFit, Baseline, Correction, Describe, Family, Improvement, Policy, Screened, Selection, StepStart, Test,
};
use ferrocal_calib::diagnose::report::{explained, Decision, Diagnosis, Finding, Unit, Verdict};
use ferrocal_calib::error::Result;
use ferrocal_lsq::linear::{fit, LinearOptions, RankPolicy, Weighting};
use nalgebra::{DMatrix, DVector};

/// A polynomial in `x` with the powers `terms` (0 and 1: the base line), fitted by least squares.
struct Polynomial {
    x: Vec<f64>,
    y: Vec<f64>,
    folds: usize,
    terms: Vec<u32>,
    /// Held-out squared errors of the current model per point.
    e0: Vec<f64>,
    /// Largest plausible coefficient of an added term.
    max_coefficient: f64,
    /// Retire the first accepted term once two are accepted (a backward check's verdict).
    prune_first: bool,
    /// Compare every candidate jointly with the others before accepting it (look-alikes).
    compare: bool,
    /// The coefficient bound is a typical range (beyond it: unusual, claimed on strong
    /// support) rather than a veto.
    soft: bool,
}

fn lstsq(x: &[f64], y: &[f64], terms: &[u32], rows: &[usize]) -> DVector<f64> {
    let a = DMatrix::from_fn(rows.len(), terms.len(), |r, c| x[rows[r]].powi(terms[c] as i32));
    let b = DVector::from_iterator(rows.len(), rows.iter().map(|&i| y[i]));
    let names: Vec<String> = terms.iter().map(|t| format!("x^{t}")).collect();
    let opts = LinearOptions::new(RankPolicy::Truncate, 1e-12);
    DVector::from_vec(fit(&a, &b, &names, &Weighting::Unit, &opts).expect("least squares").values)
}

impl Polynomial {
    fn new(x: Vec<f64>, y: Vec<f64>, max_coefficient: f64) -> Self {
        let mut p = Self {
            x,
            y,
            folds: 5,
            terms: vec![0, 1],
            e0: Vec::new(),
            max_coefficient,
            prune_first: false,
            compare: false,
            soft: false,
        };
        p.e0 = p.heldout(&p.terms.clone());
        p
    }

    /// Held-out squared error per point of a K-fold cross-validation.
    fn heldout(&self, terms: &[u32]) -> Vec<f64> {
        let n = self.x.len();
        let mut e = vec![0.0; n];
        for f in 0..self.folds {
            let train: Vec<usize> = (0..n).filter(|i| i % self.folds != f).collect();
            let c = lstsq(&self.x, &self.y, terms, &train);
            for i in (0..n).filter(|i| i % self.folds == f) {
                let pred: f64 = terms.iter().zip(c.iter()).map(|(t, c)| c * self.x[i].powi(*t as i32)).sum();
                e[i] = (self.y[i] - pred).powi(2);
            }
        }
        e
    }
}

fn rms(e: &[f64]) -> f64 {
    (e.iter().sum::<f64>() / e.len() as f64).sqrt()
}

impl Family for Polynomial {
    type Candidate = u32;
    type Effect = u32;
    type Screen = Vec<f64>;
    type Fit = ();

    fn unit(&self) -> Unit {
        Unit::Millimetre
    }

    fn begin_step(&mut self, accepted: &[u32]) -> Result<StepStart> {
        if self.prune_first && accepted.len() == 2 {
            self.prune_first = false;
            self.terms.retain(|t| *t != accepted[0]);
            self.e0 = self.heldout(&self.terms.clone());
            return Ok(StepStart::Pruned { index: 0, p_value: 0.5, change: -0.001 });
        }
        Ok(StepStart::Baseline(Baseline {
            heldout: rms(&self.e0),
            mse: self.e0.iter().sum::<f64>() / self.e0.len() as f64,
        }))
    }

    fn candidates(&self, accepted: &[u32], retired: &[u32]) -> Vec<u32> {
        [2, 3, 4].into_iter().filter(|p| !accepted.contains(p) && !retired.contains(p)).collect()
    }

    fn describe(&self, p: &u32) -> Describe {
        Describe { label: format!("x^{p}"), effect: format!("power_{p}"), joints: Vec::new(), n_params: 1 }
    }

    fn screen(&mut self, p: &u32) -> Result<Screened<Vec<f64>>> {
        let mut terms = self.terms.clone();
        terms.push(*p);
        let e1 = self.heldout(&terms);
        let d = self.e0.iter().zip(&e1).map(|(a, b)| a - b).collect();
        Ok(Screened::Scored { d, heldout: rms(&e1), data: e1 })
    }

    fn fit_all(&mut self, p: &u32, _screen: &Vec<f64>) -> Result<Option<AllFit<u32, ()>>> {
        let mut terms = self.terms.clone();
        terms.push(*p);
        let all: Vec<usize> = (0..self.x.len()).collect();
        let c = lstsq(&self.x, &self.y, &terms, &all);
        let parameters = BTreeMap::from([(format!("c{p}"), c[terms.len() - 1])]);
        Ok(Some(AllFit { effect: *p, parameters, overlap_sine: None, data: () }))
    }

    fn look_alikes(&mut self, _p: &u32, others: &[&u32]) -> Result<Vec<usize>> {
        Ok(if self.compare { (0..others.len()).collect() } else { Vec::new() })
    }

    fn screen_together(&mut self, cands: &[(&u32, &Vec<f64>)]) -> Result<Option<Vec<f64>>> {
        let mut terms = self.terms.clone();
        terms.extend(cands.iter().map(|(p, _)| **p));
        let e1 = self.heldout(&terms);
        Ok(Some(self.e0.iter().zip(&e1).map(|(a, b)| a - b).collect()))
    }

    fn plausible(&self, fit: &AllFit<u32, ()>) -> std::result::Result<(), String> {
        let c = fit.parameters.values().next().copied().unwrap_or(0.0);
        if c.abs() <= self.max_coefficient || self.soft {
            Ok(())
        } else {
            Err(format!("coefficient {c} beyond {}", self.max_coefficient))
        }
    }

    fn unusual(&self, fit: &AllFit<u32, ()>) -> Option<String> {
        let c = fit.parameters.values().next().copied().unwrap_or(0.0);
        (self.soft && c.abs() > self.max_coefficient)
            .then(|| format!("coefficient {c} beyond the usual {}", self.max_coefficient))
    }

    fn accept(&mut self, fit: AllFit<u32, ()>, e1: &Vec<f64>, decision: &Decision) -> Result<Finding<u32>> {
        self.terms.push(fit.effect);
        self.e0 = e1.clone();
        Ok(Finding {
            accepted: fit.effect,
            effect: format!("power_{}", fit.effect),
            joints: Vec::new(),
            parameters: fit.parameters,
            heldout_before: decision.heldout_before,
            heldout_after: decision.heldout_after,
            explained_fraction: explained(decision.heldout_before, decision.heldout_after),
            statement: format!("the data hold a term in x^{}", fit.effect),
            std_from_covariance: None,
            telling_input: "x".into(),
            evidence: None,
            decision: decision.clone(),
        })
    }
}

/// `n` points on [-1, 1] of `1 + 0.5 x + extra x^power` with Gaussian noise (deterministic).
fn data(n: usize, extra: Option<(u32, f64)>, noise: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    let mut uniform = move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mut x = Vec::with_capacity(n);
    let mut y = Vec::with_capacity(n);
    for i in 0..n {
        let xi = -1.0 + 2.0 * i as f64 / (n - 1) as f64;
        let gauss = (-2.0 * uniform().ln()).sqrt() * (std::f64::consts::TAU * uniform()).cos();
        let e = extra.map_or(0.0, |(p, c)| c * xi.powi(p as i32));
        x.push(xi);
        y.push(1.0 + 0.5 * xi + e + noise * gauss);
    }
    (x, y)
}

fn policy(selection: Selection) -> Policy {
    Policy {
        alpha: 0.01,
        min_improvement: 0.01,
        max_effects: 6,
        min_sin_angle: 0.05,
        test: Test::PairedT,
        correction: Correction::PerKind,
        improvement: Improvement::MseFraction,
        selection,
    }
}

fn run(extra: Option<(u32, f64)>, seed: u64, selection: Selection, max_coefficient: f64) -> Diagnosis<u32> {
    let (x, y) = data(300, extra, 0.05, seed);
    let mut family = Polynomial::new(x, y, max_coefficient);
    select(&mut family, &policy(selection)).unwrap()
}

const SELECTIONS: [Selection; 2] = [Selection::Ranked { max_checked: 4 }, Selection::SmallestP];

#[test]
fn the_one_extra_term_is_accepted_and_nothing_else() {
    for selection in SELECTIONS {
        for (power, seed) in [(2, 1), (3, 2)] {
            let d = run(Some((power, 0.3)), seed, selection, 10.0);
            let found: Vec<u32> = d.findings.iter().map(|f| f.accepted).collect();
            assert_eq!(found, vec![power], "{selection:?}: {:#?}", d.steps);
            let f = &d.findings[0];
            assert!(f.heldout_after < f.heldout_before);
            assert!(f.decision.p_corrected < 0.01);
            let c = f.parameters[&format!("c{power}")];
            assert!((c - 0.3).abs() < 0.05, "coefficient {c}");
            // The step after the acceptance declines: every row has a verdict, none accepted.
            let last = d.steps.last().unwrap();
            assert!(last.accepted.is_none());
            assert!(last
                .rows
                .iter()
                .all(|r| r.verdict != Verdict::Pending && !matches!(r.verdict, Verdict::Accepted { .. })));
            assert_eq!(d.unit.suffix(), "mm");
        }
    }
}

#[test]
fn a_straight_line_gives_no_findings() {
    for selection in SELECTIONS {
        for seed in [3, 4, 5] {
            let d = run(None, seed, selection, 10.0);
            assert!(d.findings.is_empty(), "{selection:?}, seed {seed}: {:#?}", d.findings);
            assert_eq!(d.steps.len(), 1);
            assert!(d.steps[0].rows.iter().all(|r| r.p_corrected >= r.p_value));
        }
    }
}

#[test]
fn an_implausible_term_is_declined() {
    for selection in SELECTIONS {
        let d = run(Some((2, 0.3)), 1, selection, 0.1);
        assert!(d.findings.is_empty(), "{selection:?}: {:#?}", d.findings);
        assert!(d.steps[0].rows.iter().any(|r| matches!(r.verdict, Verdict::Implausible(_))), "{:#?}", d.steps);
    }
}

#[test]
fn the_correction_counts_the_candidates() {
    // Three candidates of three kinds: the weighted and the plain Bonferroni agree (x 3).
    let d = run(None, 6, Selection::SmallestP, 10.0);
    for r in &d.steps[0].rows {
        assert!((r.p_corrected - (3.0 * r.p_value).min(1.0)).abs() < 1e-12, "{r:?}");
    }
}

#[test]
fn a_retired_effect_leaves_the_findings_and_is_not_proposed_again() {
    let (x, y) = data(300, None, 0.05, 7);
    // Truth with two extra terms: x^2 and x^3.
    let y: Vec<f64> = x.iter().zip(&y).map(|(x, y)| y + 0.3 * x * x + 0.3 * x.powi(3)).collect();
    let mut family = Polynomial::new(x, y, 10.0);
    family.prune_first = true;
    let d = select(&mut family, &policy(Selection::Ranked { max_checked: 4 })).unwrap();
    assert_eq!(d.retired.len(), 1, "{:#?}", d.steps);
    // The second term stays; the first leaves the findings (x^4 may take over what the retired
    // x^2 explained: it is still open).
    let kept: Vec<u32> = d.findings.iter().map(|f| f.accepted).collect();
    assert!(!kept.is_empty() && !kept.contains(&d.retired[0]), "{kept:?}, retired {:?}", d.retired);
    assert_eq!(d.notes.len(), 1);
    assert!(
        d.notes[0].starts_with(&format!("power_{} on joints [] was accepted first but dropped", d.retired[0])),
        "{}",
        d.notes[0]
    );
    // The retired term is never a candidate again.
    assert!(d.steps.len() >= 3);
    let after_prune = &d.steps[2..];
    assert!(after_prune.iter().flat_map(|s| &s.rows).all(|r| r.label != format!("x^{}", d.retired[0])));
}

#[test]
fn a_vetoed_candidate_explains_nothing_away_and_an_unusual_one_is_claimed_with_words() {
    // The truth holds 0.3 x^4. x^2 alone fits the even bulge well enough to be significant
    // (coefficient about 0.24).
    // - With a veto at 0.265 (fitted: 0.275), x^4 is rejected, and a rejected candidate never
    //   explains another away: x^2, the best reading that is allowed, is claimed whether or not
    //   the two are compared jointly (before issue [physics-real] the vetoed x^4 explained x^2
    //   away and nothing was claimed while the data held a large effect).
    // - With 0.265 as a typical range instead, x^4 is unusual, strongly supported, and claimed
    //   with its words; x^2 is not claimed beside it.
    for compare in [false, true] {
        let (x, y) = data(300, Some((4, 0.3)), 0.05, 8);
        let mut family = Polynomial::new(x, y, 0.265);
        family.compare = compare;
        let d = select(&mut family, &policy(Selection::Ranked { max_checked: 4 })).unwrap();
        let found: Vec<u32> = d.findings.iter().map(|f| f.accepted).collect();
        let row = |label: &str| d.steps[0].rows.iter().find(|r| r.label == label).unwrap().verdict.clone();
        assert!(matches!(row("x^4"), Verdict::Implausible(_)), "{:#?}", d.steps[0]);
        assert!(matches!(row("x^2"), Verdict::Accepted { .. }), "{:#?}", d.steps[0]);
        assert_eq!(found, vec![2], "{:#?}", d.steps);
    }
    for compare in [false, true] {
        let (x, y) = data(300, Some((4, 0.3)), 0.05, 8);
        let mut family = Polynomial::new(x, y, 0.265);
        family.compare = compare;
        family.soft = true;
        let d = select(&mut family, &policy(Selection::Ranked { max_checked: 4 })).unwrap();
        let found: Vec<u32> = d.findings.iter().map(|f| f.accepted).collect();
        assert_eq!(found, vec![4], "{:#?}", d.steps);
        let caution = d.findings[0].decision.caution.clone().unwrap_or_default();
        assert!(caution.contains("beyond the usual"), "{caution}");
    }
}
