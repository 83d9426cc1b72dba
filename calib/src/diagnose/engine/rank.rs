//! The engine's ranking of a step's candidates: the cheap checks, the joint comparison of look-alikes, the confirmations.

use super::*;

/// Ranked examination: by improvement, significant ones first with parsimony, each checked in
/// turn until one passes.
#[allow(clippy::type_complexity)]
pub(super) fn ranked<F: Family>(
    family: &mut F,
    policy: &Policy,
    entries: &mut [Entry<F>],
    accepted: &[F::Effect],
    max_checked: usize,
    multiplier: &dyn Fn(&Describe) -> usize,
    notes: &mut Vec<String>,
) -> Result<Option<(usize, AllFit<F::Effect, F::Fit>, Decision)>> {
    entries.sort_by(|a, b| b.row.improvement.total_cmp(&a.row.improvement));
    for e in entries.iter_mut() {
        if e.d.is_none() {
            continue;
        }
        if e.row.improvement < policy.min_improvement {
            e.row.verdict = Verdict::TooSmall;
        } else if e.row.p_corrected >= policy.alpha {
            e.row.verdict = Verdict::NotSignificant;
        }
    }
    let sig_idx = significant(policy, entries);
    // Parsimony: among the candidates the held-out data cannot tell from the best one, the one
    // with the fewest parameters first.
    let order: Vec<usize> = match sig_idx.first() {
        None => Vec::new(),
        Some(&best) => {
            let mut tw: Vec<usize> =
                sig_idx.iter().copied().filter(|&i| i == best || twins(entries, best, i)).collect();
            tw.sort_by(|&a, &b| {
                entries[a]
                    .describe
                    .n_params
                    .cmp(&entries[b].describe.n_params)
                    .then(entries[b].row.improvement.total_cmp(&entries[a].row.improvement))
            });
            let mut o = tw.clone();
            o.extend(sig_idx.iter().copied().filter(|i| !tw.contains(i)));
            o
        }
    };
    // One joint at a time first: a candidate that groups others of its kind (the same effect
    // on a strict superset of their joints, e.g. compliance on every loaded joint together) is
    // examined only after all the others, so that it is claimed only when no smaller reading
    // passes (an effect spread thin over several joints), never in place of one that does.
    let groups: Vec<usize> = order
        .iter()
        .copied()
        .filter(|&i| {
            entries.iter().any(|o| {
                o.row.effect == entries[i].row.effect
                    && o.row.joints.len() < entries[i].row.joints.len()
                    && o.row.joints.iter().all(|j| entries[i].row.joints.contains(j))
            })
        })
        .collect();
    let order: Vec<usize> =
        order.iter().copied().filter(|i| !groups.contains(i)).chain(groups.iter().copied()).collect();
    // Candidates rejected this step: none of them may explain another one away.
    let mut rejected: Vec<usize> = Vec::new();
    let mut confirmed = 0;
    let mut chosen = None;
    for idx in order {
        if confirmed >= max_checked || chosen.is_some() {
            entries[idx].row.verdict = Verdict::NotExamined;
            continue;
        }
        let (fit, caution) = match examine(family, policy, entries, idx)? {
            Examined::Rejected(verdict) => {
                entries[idx].row.verdict = verdict;
                rejected.push(idx);
                continue;
            }
            Examined::Admissible { fit, caution } => (fit, caution),
        };
        let relative_std = match family.stability(&fit, entries[idx].screen.as_ref().expect("examined")) {
            Ok(r) => r,
            Err(why) => {
                entries[idx].row.verdict = Verdict::Unstable(why);
                rejected.push(idx);
                continue;
            }
        };
        if let Some(verdict) = separate(family, policy, entries, idx, &rejected)? {
            if let Verdict::NotSeparable { with, p_added, p_rival_added } = &verdict {
                notes.push(format!(
                    "{} and {with} cannot be told apart on this recording: fitted together, neither improves the held-out fit of the other (p = {} and p = {}); neither is claimed",
                    entries[idx].row.label,
                    sig(*p_added, 2),
                    sig(*p_rival_added, 2)
                ));
            }
            entries[idx].row.verdict = verdict;
            rejected.push(idx);
            continue;
        }
        let mut decision = Decision::of_row(&entries[idx].row, relative_std, fit.overlap_sine, caution.clone());
        let candidate = entries[idx].candidate.clone();
        let screen = entries[idx].screen.as_ref().expect("checked above");
        confirmed += 1;
        match family.confirm(&candidate, accepted, screen)? {
            None => {}
            Some(Err(why)) => {
                entries[idx].row.verdict = Verdict::RefitFailed(why);
                rejected.push(idx);
                continue;
            }
            Some(Ok(c)) => {
                let t = paired_test(&c.d);
                let improvement = t.mean / c.mse;
                let p_corrected = bonferroni(t.p_value, multiplier(&entries[idx].describe));
                if p_corrected >= policy.alpha || improvement < policy.min_improvement {
                    entries[idx].row.verdict = Verdict::NotConfirmed { improvement, p_corrected };
                    rejected.push(idx);
                    continue;
                }
                if let Some(why) = &caution {
                    if !strongly_supported(policy, p_corrected, improvement) {
                        entries[idx].row.verdict =
                            Verdict::Implausible(unusual_rejection(policy, why, p_corrected, improvement));
                        rejected.push(idx);
                        continue;
                    }
                }
                decision.p_corrected = p_corrected;
                decision.p_uncorrected = t.p_value;
                decision.heldout_before = c.heldout_before;
                decision.heldout_after = c.heldout_after;
            }
        }
        entries[idx].row.verdict = Verdict::Accepted { p_corrected: decision.p_corrected };
        chosen = Some((idx, fit, decision));
    }
    Ok(chosen)
}

/// The outcome of the cheap checks of a significant candidate.
pub(super) enum Examined<E, F> {
    /// Rejected, with the verdict.
    Rejected(Verdict),
    /// It may be claimed: its all-data fit, and the words when it is unusual (then strongly
    /// supported on the screening).
    Admissible {
        /// The all-data fit.
        fit: AllFit<E, F>,
        /// [`Family::unusual`]'s words.
        caution: Option<String>,
    },
}

/// The cheap checks of candidate `idx` (all-data fit, overlap with the base model, physical
/// possibility, and for an unusual effect strong support); records its parameters in its row.
pub(super) fn examine<F: Family>(
    family: &mut F,
    policy: &Policy,
    entries: &mut [Entry<F>],
    idx: usize,
) -> Result<Examined<F::Effect, F::Fit>> {
    let Some(screen) = entries[idx].screen.as_ref() else {
        return Ok(Examined::Rejected(Verdict::Unscored(NOT_APPLICABLE.into())));
    };
    let Some(fit) = family.fit_all(&entries[idx].candidate, screen)? else {
        return Ok(Examined::Rejected(Verdict::Unscored(NOT_APPLICABLE.into())));
    };
    let row = &mut entries[idx].row;
    row.parameters = fit.parameters.clone();
    row.overlap_sine = fit.overlap_sine;
    if let Some(sa) = fit.overlap_sine {
        if sa < policy.min_sin_angle {
            return Ok(Examined::Rejected(Verdict::Overlap(sa)));
        }
    }
    if let Err(why) = family.plausible(&fit) {
        return Ok(Examined::Rejected(Verdict::Implausible(why)));
    }
    let caution = family.unusual(&fit);
    if let Some(why) = &caution {
        let (p, improvement) = (entries[idx].row.p_corrected, entries[idx].row.improvement);
        if !strongly_supported(policy, p, improvement) {
            return Ok(Examined::Rejected(Verdict::Implausible(unusual_rejection(policy, why, p, improvement))));
        }
    }
    Ok(Examined::Admissible { fit, caution })
}

/// The level at which a candidate counts as adding to a look-alike in the joint comparison
/// (uncorrected: the candidate is already significant on its own; the test only asks whether
/// its own part survives next to the look-alike).
pub const SEPARATION_LEVEL: f64 = 0.05;

/// The joint comparison of candidate `idx` with its look-alikes (the family's
/// [`Family::look_alikes`] among the significant candidates): each pair is fitted together and the
/// per-unit held-out improvement each adds to the other is tested (one-sided paired t test).
/// The candidate stands against a look-alike when it adds a significant improvement to it
/// (`p <` [`SEPARATION_LEVEL`]); otherwise it is rejected as explained by the look-alike when the look-alike
/// adds a significant one to it (`p < alpha` over the look-alikes, Bonferroni). When neither
/// adds anything, the two are not separable and the candidate is not claimed. A look-alike with
/// more parameters than the candidate never stands in its way (parsimony: the simpler reading
/// is examined first and stands). Look-alikes already rejected this step (`rejected`), or that
/// fail their own cheap checks (all-data fit, overlap, possibility, support of an unusual
/// size), are no rivals: a rejected reading never explains another one away.
/// `None`: it stands against every look-alike.
pub(super) fn separate<F: Family>(
    family: &mut F,
    policy: &Policy,
    entries: &mut [Entry<F>],
    idx: usize,
    rejected: &[usize],
) -> Result<Option<Verdict>> {
    // A rejected candidate never explains another one away: only those not rejected this step
    // that pass their own cheap checks (fit, overlap, possibility, support) can be rivals.
    let mut scored: Vec<usize> = Vec::new();
    for i in significant(policy, entries) {
        if i == idx || rejected.contains(&i) {
            continue;
        }
        if matches!(examine(family, policy, entries, i)?, Examined::Admissible { .. }) {
            scored.push(i);
        }
    }
    if scored.is_empty() {
        return Ok(None);
    }
    let others: Vec<&F::Candidate> = scored.iter().map(|&i| &entries[i].candidate).collect();
    let alikes: Vec<usize> =
        family.look_alikes(&entries[idx].candidate, &others)?.into_iter().map(|k| scored[k]).collect();
    let (Some(d_c), Some(s_c)) = (entries[idx].d.as_ref(), entries[idx].screen.as_ref()) else { return Ok(None) };
    let m = alikes.len().max(1);
    let mut unresolved: Option<Verdict> = None;
    for r in alikes {
        let (Some(d_r), Some(s_r)) = (entries[r].d.as_ref(), entries[r].screen.as_ref()) else { continue };
        let Some(d_pair) = family.screen_together(&[(&entries[idx].candidate, s_c), (&entries[r].candidate, s_r)])?
        else {
            continue;
        };
        let added: Vec<f64> = d_pair.iter().zip(d_r).map(|(p, r)| p - r).collect();
        let rival_added: Vec<f64> = d_pair.iter().zip(d_c).map(|(p, c)| p - c).collect();
        let p_added = paired_test(&added).p_value;
        if p_added < SEPARATION_LEVEL {
            continue;
        }
        let p_rival_added = bonferroni(paired_test(&rival_added).p_value, m);
        let with = entries[r].row.label.clone();
        // Parsimony: a look-alike with more parameters than the candidate does not displace it
        // (its extra freedom, e.g. a searched period, can mimic a simpler effect's shape); the
        // simpler reading stands, as in the examination order.
        if entries[r].describe.n_params > entries[idx].describe.n_params {
            continue;
        }
        if p_rival_added < policy.alpha {
            return Ok(Some(Verdict::Explained { by: with, p_added, p_rival_added }));
        }
        // Neither adds to the other: not separable.
        if unresolved.is_none() {
            unresolved = Some(Verdict::NotSeparable { with, p_added, p_rival_added });
        }
    }
    Ok(unresolved)
}
