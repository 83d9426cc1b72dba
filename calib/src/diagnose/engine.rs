//! The one diagnose engine: cross-validated forward selection over the candidates of a
//! [`Family`].
//!
//! A family knows its physics: which candidate effects the data can test, how to fit the base
//! model plus a candidate on training folds and score it on the held-out folds ([`Family::screen`]),
//! how to fit it on all the data, whether the result is physically plausible and stable, and how
//! to add an accepted effect to its model. The engine knows the statistics and runs them once for
//! every family:
//!
//! 1. each step, the family proposes the open candidates (those no accepted or retired effect
//!    covers); the search stops when there are none or [`Policy::max_effects`] are accepted;
//! 2. each candidate's held-out improvement (per held-out unit: a pose, a view) is tested with a
//!    one-sided paired test ([`Test`]), corrected for the candidates of the step ([`Correction`]:
//!    Bonferroni over all of them, or weighted so that every kind of effect gets an equal share
//!    of `alpha`);
//! 3. the candidates are examined in the order of the [`Selection`]: the overlap with the base
//!    model (the sine of the angle between the effect's columns and the base model's, when the
//!    family measures it), plausibility of sign and size, stability over the folds, and, when the
//!    family has one, a confirmation by full refits that is tested again; with ranked
//!    examination, before the confirmation, a joint comparison with the candidate's look-alikes
//!    ([`Family::look_alikes`], [`Family::screen_together`]): a candidate that adds nothing to
//!    a look-alike which still adds to it is rejected, and two that add nothing to each other are
//!    both left unclaimed ([`Verdict::Explained`], [`Verdict::NotSeparable`]);
//! 4. the first candidate that passes is accepted and added to the family's model, and the
//!    search repeats; a family may also retire an earlier effect that later ones made
//!    unnecessary ([`StepStart::Pruned`]).
//!
//! Every candidate of every step is kept as a [`CandidateRow`] with a structured [`Verdict`];
//! accepted effects are [`Finding`]s; the family writes the words.

use std::collections::BTreeMap;

use super::report::{sig, CandidateRow, Decision, Diagnosis, Finding, StepRows, Unit, Verdict};
use super::stats::{bonferroni, paired_test, sign_test};
use crate::error::Result;

mod rank;
use rank::ranked;
pub use rank::SEPARATION_LEVEL;

/// The test of a candidate's held-out improvement over the held-out units.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Test {
    /// One-sided paired t test of `mean(d) > 0`.
    PairedT,
    /// The smaller p-value of the one-sided sign test and the paired t test, corrected for both
    /// (for heavy-tailed per-unit differences, e.g. camera views).
    SignOrT,
}

/// The multiple-testing correction of a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Correction {
    /// Bonferroni over the step's candidates.
    PerCandidate,
    /// Weighted Bonferroni: every kind of effect gets an equal share of `alpha`, split equally
    /// among its candidates (a kind with many joints and periods does not crowd out the others).
    PerKind,
}

/// How the size of an improvement is measured against [`Policy::min_improvement`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Improvement {
    /// Mean per-unit improvement as a fraction of the baseline's held-out mean squared error.
    MseFraction,
    /// `1 - after / before` of the held-out RMS figures.
    RmsFraction,
}

/// Which candidates are examined, and in what order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Selection {
    /// Only the candidate with the smallest corrected p-value (ties to the lower held-out
    /// figure) is examined; it is accepted when significant, large enough and plausible.
    SmallestP,
    /// Candidates are ranked by improvement; the significant ones are examined in that order
    /// (candidates the held-out data cannot tell from the best one, fewest parameters first),
    /// until one passes every check; at most `max_checked` of them reach the confirmation
    /// (candidates the cheap checks reject do not count, so the search goes on after them).
    Ranked {
        /// Candidates examined per step.
        max_checked: usize,
    },
}

/// The statistical settings of a selection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Policy {
    /// Family-wise significance level of each step.
    pub alpha: f64,
    /// Smallest improvement worth a claim (see [`Improvement`]).
    pub min_improvement: f64,
    /// Most effects accepted.
    pub max_effects: usize,
    /// Smallest sine of the angle between an effect's columns and the base model's.
    pub min_sin_angle: f64,
    /// Test of the per-unit improvements.
    pub test: Test,
    /// Multiple-testing correction.
    pub correction: Correction,
    /// Size measure of an improvement.
    pub improvement: Improvement,
    /// Order of examination.
    pub selection: Selection,
}

impl Policy {
    /// The policy of the image families (the camera, the stereo pair, the hand-eye chain's
    /// physics): every effect the data support, examined by smallest p-value, the sign test or
    /// the t test per held-out unit, Bonferroni over both and the candidates, the improvement
    /// as a fraction of the held-out RMS.
    pub fn held_out_images(alpha: f64, min_improvement: f64) -> Self {
        Self {
            alpha,
            min_improvement,
            max_effects: usize::MAX,
            min_sin_angle: 0.0,
            test: Test::SignOrT,
            correction: Correction::PerCandidate,
            improvement: Improvement::RmsFraction,
            selection: Selection::SmallestP,
        }
    }
}

/// The current model's held-out figures at the start of a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Baseline {
    /// Held-out figure (RMS in the family's unit) of the current model.
    pub heldout: f64,
    /// Held-out mean squared error per unit, in the units of [`Screened::d`].
    pub mse: f64,
}

impl Baseline {
    /// The baseline of per-unit held-out errors, each given as (sum of squared errors, number
    /// of errors): the pooled mean squared error and its root.
    pub fn of_pooled(errors: &[(f64, usize)]) -> Self {
        let (s, n) = errors.iter().fold((0.0, 0usize), |(a, b), (s, n)| (a + s, b + n));
        let mse = s / n.max(1) as f64;
        Self { heldout: mse.sqrt(), mse }
    }
}

/// How a step starts.
#[derive(Clone, Debug, PartialEq)]
pub enum StepStart {
    /// The current model's baseline; the step proceeds.
    Baseline(Baseline),
    /// The accepted effect at `index` was made unnecessary by later ones: the family has
    /// refitted without it, the engine retires it and starts the step again.
    Pruned {
        /// Index among the accepted effects.
        index: usize,
        /// p-value of leaving it out (paired test).
        p_value: f64,
        /// Change of the held-out error leaving it out causes, fraction (negative: worse).
        change: f64,
    },
}

/// A candidate's name, as the rows and the correction see it.
#[derive(Clone, Debug, PartialEq)]
pub struct Describe {
    /// Readable label, unique within a step.
    pub label: String,
    /// Effect name (`shared/spec/diagnose.md`); also the kind of the weighted correction.
    pub effect: String,
    /// 1-based joints (empty when not tied to a joint).
    pub joints: Vec<usize>,
    /// Free parameters (parsimony).
    pub n_params: usize,
}

/// The held-out scores of one candidate.
pub enum Screened<S> {
    /// Scored.
    Scored {
        /// Per held-out unit: squared error before minus after.
        d: Vec<f64>,
        /// Held-out figure with the candidate (family unit).
        heldout: f64,
        /// The family's data of this cross-validation.
        data: S,
    },
    /// Could not be scored: listed with this held-out figure and verdict.
    Unscored {
        /// Held-out figure to list.
        heldout: f64,
        /// Why.
        why: String,
    },
    /// Not applicable at the current model: left out of the step.
    Skip,
}

/// A candidate fitted on all the data.
pub struct AllFit<E, F> {
    /// The effect as it would be accepted (e.g. with its period chosen on all the data).
    pub effect: E,
    /// Its parameters (names with units).
    pub parameters: BTreeMap<String, f64>,
    /// Sine of the angle between its columns and the base model's, when measured.
    pub overlap_sine: Option<f64>,
    /// The family's fit.
    pub data: F,
}

/// A confirmation by full refits on the folds.
#[derive(Clone, Debug, PartialEq)]
pub struct Confirmation {
    /// Per held-out unit: squared error before minus after.
    pub d: Vec<f64>,
    /// Baseline mean squared error per unit (same units as `d`).
    pub mse: f64,
    /// Held-out figure before.
    pub heldout_before: f64,
    /// Held-out figure after.
    pub heldout_after: f64,
}

/// A physical family of candidate effects (kinematic, camera, force sensor, ...).
pub trait Family {
    /// A proposed candidate.
    type Candidate: Clone;
    /// An accepted effect.
    type Effect: Clone;
    /// The family's data of a candidate's cross-validation.
    type Screen;
    /// The family's fit of a candidate on all the data.
    type Fit;

    /// The unit of the held-out figures.
    fn unit(&self) -> Unit;
    /// Prepares a step at the current model (with `accepted` effects).
    fn begin_step(&mut self, accepted: &[Self::Effect]) -> Result<StepStart>;
    /// The open candidates: those no accepted or retired effect covers.
    fn candidates(&self, accepted: &[Self::Effect], retired: &[Self::Effect]) -> Vec<Self::Candidate>;
    /// Name, kind and size of a candidate.
    fn describe(&self, candidate: &Self::Candidate) -> Describe;
    /// Fits base model plus candidate on the training folds and scores it on the held-out folds.
    fn screen(&mut self, candidate: &Self::Candidate) -> Result<Screened<Self::Screen>>;
    /// Fits base model plus candidate on all the data (`None`: not applicable).
    fn fit_all(
        &mut self,
        candidate: &Self::Candidate,
        screen: &Self::Screen,
    ) -> Result<Option<AllFit<Self::Effect, Self::Fit>>>;
    /// Physical possibility of sign and size: `Err` vetoes the candidate whatever the data say
    /// (keep these for what no machine can do: a linear model stretched past its meaning).
    fn plausible(&self, fit: &AllFit<Self::Effect, Self::Fit>) -> std::result::Result<(), String>;
    /// Whether a possible effect is unusual for its kind (larger than the family's machines
    /// typically show, or of an unusual sign), in words; `None` when it is typical. An unusual
    /// effect is claimed only on strong held-out evidence ([`STRONG_P_FACTOR`],
    /// [`STRONG_IMPROVEMENT_FACTOR`]) and then reported with these words: evidence, not a veto.
    fn unusual(&self, _fit: &AllFit<Self::Effect, Self::Fit>) -> Option<String> {
        None
    }
    /// Stability over the folds; the relative standard deviation of the main parameter.
    fn stability(
        &self,
        _fit: &AllFit<Self::Effect, Self::Fit>,
        _screen: &Self::Screen,
    ) -> std::result::Result<f64, String> {
        Ok(0.0)
    }
    /// Confirmation by full refits (`None`: the family has none, the screening counts). The
    /// inner error says why the refit failed (the candidate is rejected), the outer one fails
    /// the analysis.
    fn confirm(
        &mut self,
        _candidate: &Self::Candidate,
        _accepted: &[Self::Effect],
        _screen: &Self::Screen,
    ) -> Result<Option<std::result::Result<Confirmation, String>>> {
        Ok(None)
    }
    /// The other scored candidates of the step that can leave residuals like `candidate`'s
    /// (look-alikes, e.g. a backlash and a scale error of the same joint when the approach
    /// direction follows the angle): indices into `others`. The default has none.
    fn look_alikes(&mut self, _candidate: &Self::Candidate, _others: &[&Self::Candidate]) -> Result<Vec<usize>> {
        Ok(Vec::new())
    }
    /// Per held-out unit: the squared error before minus after of the base model plus all
    /// `candidates` fitted together on the training folds (`None`: the family cannot).
    fn screen_together(&mut self, _candidates: &[(&Self::Candidate, &Self::Screen)]) -> Result<Option<Vec<f64>>> {
        Ok(None)
    }
    /// Adds the accepted effect to the model and describes it.
    fn accept(
        &mut self,
        fit: AllFit<Self::Effect, Self::Fit>,
        screen: &Self::Screen,
        decision: &Decision,
    ) -> Result<Finding<Self::Effect>>;
}

/// The verdict of a candidate the family cannot fit on all the data.
const NOT_APPLICABLE: &str = "not applicable when fitted on all the data";

/// An unusual effect ([`Family::unusual`]) is claimed only when its corrected p-value is below
/// `alpha` times this: a soft prior that asks more evidence of an effect outside the typical
/// range, instead of a bound that vetoes it.
pub const STRONG_P_FACTOR: f64 = 0.01;

/// An unusual effect must also remove at least this many times [`Policy::min_improvement`] of
/// the held-out error.
pub const STRONG_IMPROVEMENT_FACTOR: f64 = 5.0;

/// Whether a candidate with corrected p-value `p` and held-out improvement `improvement` has
/// the strong support an unusual effect needs.
pub fn strongly_supported(policy: &Policy, p: f64, improvement: f64) -> bool {
    p < policy.alpha * STRONG_P_FACTOR && improvement >= policy.min_improvement * STRONG_IMPROVEMENT_FACTOR
}

/// The verdict words of an unusual effect whose support is not strong enough.
fn unusual_rejection(policy: &Policy, why: &str, p: f64, improvement: f64) -> String {
    format!(
        "{why}; an effect this unusual is claimed only on strong held-out support (corrected p below {}, improvement at least {:.0} %), and it has p = {}, {:.1} %",
        sig(policy.alpha * STRONG_P_FACTOR, 2),
        policy.min_improvement * STRONG_IMPROVEMENT_FACTOR * 100.0,
        sig(p, 2),
        improvement * 100.0
    )
}

/// One candidate while its step runs.
struct Entry<F: Family> {
    candidate: F::Candidate,
    describe: Describe,
    row: CandidateRow,
    d: Option<Vec<f64>>,
    screen: Option<F::Screen>,
}

/// Runs the cross-validated forward selection of `family`.
pub fn select<F: Family>(family: &mut F, policy: &Policy) -> Result<Diagnosis<F::Effect>> {
    let mut out = Diagnosis {
        unit: family.unit(),
        steps: Vec::new(),
        findings: Vec::new(),
        retired: Vec::new(),
        capped: false,
        notes: Vec::new(),
    };
    let mut accepted: Vec<F::Effect> = Vec::new();
    loop {
        let baseline = match family.begin_step(&accepted)? {
            StepStart::Baseline(b) => b,
            StepStart::Pruned { index, p_value, change } => {
                let gone = accepted.remove(index);
                let f = out.findings.remove(index);
                out.notes.push(format!(
                    "{} on joints {:?} was accepted first but dropped once later effects were modelled: leaving it out changes the held-out error by {:.2} % (p = {}); its statement was: {}",
                    f.effect,
                    f.joints,
                    -change * 100.0,
                    sig(p_value, 2),
                    f.statement
                ));
                out.retired.push(gone);
                continue;
            }
        };
        let open = family.candidates(&accepted, &out.retired);
        if open.is_empty() || accepted.len() >= policy.max_effects {
            out.capped = !open.is_empty();
            break;
        }
        let m = open.len();
        let described: Vec<Describe> = open.iter().map(|c| family.describe(c)).collect();
        let multiplier = |d: &Describe| -> usize {
            match (policy.correction, policy.test) {
                (Correction::PerCandidate, Test::PairedT) => m,
                (Correction::PerCandidate, Test::SignOrT) => 2 * m,
                (Correction::PerKind, test) => {
                    let mut kinds: Vec<&str> = described.iter().map(|d| d.effect.as_str()).collect();
                    kinds.sort_unstable();
                    kinds.dedup();
                    let per = kinds.len() * described.iter().filter(|o| o.effect == d.effect).count();
                    if test == Test::SignOrT {
                        2 * per
                    } else {
                        per
                    }
                }
            }
        };
        let mut entries: Vec<Entry<F>> = Vec::new();
        for (candidate, describe) in open.into_iter().zip(described.iter().cloned()) {
            let mut row = CandidateRow {
                label: describe.label.clone(),
                effect: describe.effect.clone(),
                joints: describe.joints.clone(),
                heldout_before: baseline.heldout,
                heldout_after: f64::NAN,
                improvement: f64::NAN,
                p_value: 1.0,
                p_corrected: 1.0,
                parameters: BTreeMap::new(),
                overlap_sine: None,
                verdict: Verdict::Pending,
            };
            let (d, screen) = match family.screen(&candidate)? {
                Screened::Skip => continue,
                Screened::Unscored { heldout, why } => {
                    row.heldout_after = heldout;
                    row.verdict = Verdict::Unscored(why);
                    (None, None)
                }
                Screened::Scored { d, heldout, data } => {
                    let t = paired_test(&d);
                    let p = match policy.test {
                        Test::PairedT => t.p_value,
                        Test::SignOrT => sign_test(&d).min(t.p_value),
                    };
                    row.heldout_after = heldout;
                    row.p_value = p;
                    row.p_corrected = bonferroni(p, multiplier(&describe));
                    row.improvement = match policy.improvement {
                        Improvement::MseFraction => t.mean / baseline.mse,
                        Improvement::RmsFraction => 1.0 - heldout / baseline.heldout,
                    };
                    (Some(d), Some(data))
                }
            };
            entries.push(Entry { candidate, describe, row, d, screen });
        }
        let chosen = match policy.selection {
            Selection::SmallestP => smallest_p(family, policy, &mut entries)?,
            Selection::Ranked { max_checked } => {
                ranked(family, policy, &mut entries, &accepted, max_checked, &multiplier, &mut out.notes)?
            }
        };
        let Some((idx, fit, mut decision)) = chosen else {
            out.steps.push(StepRows {
                rows: entries.into_iter().map(|e| e.row).collect(),
                accepted: None,
                candidates_tried: m,
            });
            break;
        };
        decision.candidates_tried = m;
        decision.alternatives = alternatives(policy, &entries, idx);
        let screen = entries[idx].screen.take();
        let label = entries[idx].row.label.clone();
        out.steps.push(StepRows {
            rows: entries.into_iter().map(|e| e.row).collect(),
            accepted: Some(label),
            candidates_tried: m,
        });
        let Some(screen) = screen else { break };
        let effect = fit.effect.clone();
        let finding = family.accept(fit, &screen, &decision)?;
        out.findings.push(finding);
        accepted.push(effect);
    }
    Ok(out)
}

/// The smallest corrected p-value (ties to the lower held-out figure) is examined alone.
#[allow(clippy::type_complexity)]
fn smallest_p<F: Family>(
    family: &mut F,
    policy: &Policy,
    entries: &mut [Entry<F>],
) -> Result<Option<(usize, AllFit<F::Effect, F::Fit>, Decision)>> {
    let mut best: Option<usize> = None;
    for (i, e) in entries.iter().enumerate() {
        if e.d.is_none() {
            continue;
        }
        let better = best.is_none_or(|b| {
            let (bp, ba) = (entries[b].row.p_corrected, entries[b].row.heldout_after);
            let (p, a) = (e.row.p_corrected, e.row.heldout_after);
            p < bp * 0.999 || (p <= bp * 1.001 && a < ba)
        });
        if better {
            best = Some(i);
        }
    }
    let Some(b) = best else { return Ok(None) };
    let screen = entries[b].screen.as_ref().expect("a scored candidate has its screening data");
    let fit = family.fit_all(&entries[b].candidate, screen)?;
    let row = &entries[b].row;
    let (p, improvement) = (row.p_corrected, row.improvement);
    let caution = fit.as_ref().and_then(|f| family.unusual(f));
    let plausible = fit.as_ref().map(|f| {
        family.plausible(f).and_then(|()| match &caution {
            Some(why) if !strongly_supported(policy, p, improvement) => {
                Err(unusual_rejection(policy, why, p, improvement))
            }
            _ => Ok(()),
        })
    });
    let accepted = p < policy.alpha && improvement >= policy.min_improvement && matches!(plausible, Some(Ok(())));
    for (i, e) in entries.iter_mut().enumerate() {
        if e.row.verdict != Verdict::Pending {
            continue;
        }
        e.row.verdict = if i != b {
            Verdict::NotBest
        } else if fit.is_none() {
            Verdict::Unscored(NOT_APPLICABLE.into())
        } else if accepted {
            Verdict::Accepted { p_corrected: p }
        } else if let Some(Err(why)) = &plausible {
            Verdict::Implausible(why.clone())
        } else if p >= policy.alpha {
            Verdict::NotSignificant
        } else {
            Verdict::TooSmall
        };
    }
    if let Some(f) = &fit {
        entries[b].row.parameters = f.parameters.clone();
        entries[b].row.overlap_sine = f.overlap_sine;
    }
    match fit {
        Some(fit) if accepted => {
            let decision = Decision::of_row(&entries[b].row, 0.0, fit.overlap_sine, caution);
            Ok(Some((b, fit, decision)))
        }
        _ => Ok(None),
    }
}

/// Whether the held-out data cannot tell candidate `i` from candidate `j` (paired test of their
/// per-unit improvements, p > 0.05).
fn twins<F: Family>(entries: &[Entry<F>], i: usize, j: usize) -> bool {
    match (&entries[i].d, &entries[j].d) {
        (Some(a), Some(b)) => {
            let diff: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
            paired_test(&diff).p_value > 0.05
        }
        _ => false,
    }
}

/// The significant candidates (improvement and corrected p-value), in the order of the rows.
fn significant<F: Family>(policy: &Policy, entries: &[Entry<F>]) -> Vec<usize> {
    entries
        .iter()
        .enumerate()
        .filter(|(_, e)| {
            e.d.is_some() && e.row.p_corrected < policy.alpha && e.row.improvement >= policy.min_improvement
        })
        .map(|(i, _)| i)
        .collect()
}

/// Other significant candidates of another effect that the held-out data cannot tell from the
/// accepted one.
fn alternatives<F: Family>(policy: &Policy, entries: &[Entry<F>], idx: usize) -> Vec<String> {
    if !matches!(policy.selection, Selection::Ranked { .. }) {
        return Vec::new();
    }
    significant(policy, entries)
        .into_iter()
        .filter(|&i| {
            // Not another form of the same effect on the same joints, nor a group that holds
            // it (nested: the group was examined only because no smaller reading was claimed).
            i != idx
                && !(entries[i].row.effect == entries[idx].row.effect
                    && entries[idx].row.joints.iter().all(|j| entries[i].row.joints.contains(j)))
        })
        .filter(|&i| twins(entries, idx, i))
        .map(|i| entries[i].row.label.clone())
        .collect()
}
