//! Pose selection ([planning] issue): greedy deletion with rank-one downdates, exchange, the
//! criteria against the count, and the selection against random subsets on an L1 pool.

use ferrocal_calib::design::criteria::{CriteriaSummary, Criterion};
use ferrocal_calib::design::kinematic::{kinematic_pool, predict};
use ferrocal_calib::design::pool::InformationPool;
use ferrocal_calib::design::selection::{exchange, greedy_deletion, select, SelectionSettings};
use ferrocal_calib::kinematic::{design_jacobian, KinematicOptions, ModelParams};
use ferrocal_robot::{Kinematics, RobotModel};
use nalgebra::{DMatrix, Isometry3, Matrix3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn l1_options() -> KinematicOptions {
    KinematicOptions {
        model_params: ModelParams::All,
        estimate_device_frame: false,
        fixed_device_frame: Some(Isometry3::identity()),
        joint_offsets: false,
        estimate_tool: false,
        use_orientation: false,
        ..KinematicOptions::default()
    }
}

/// 480 random L1 configurations (carts within +-0.8 m) with a forward-kinematics solution.
fn l1_poses(n: usize, seed: u64) -> (RobotModel, Vec<Vec<f64>>) {
    let model = RobotModel::load("gantry-tau-l1").unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut poses = Vec::with_capacity(n);
    while poses.len() < n {
        let q: Vec<f64> = (0..3).map(|_| rng.random_range(-0.8..0.8)).collect();
        if model.forward(&q).is_ok() {
            poses.push(q);
        }
    }
    (model, poses)
}

/// The whitened pool of 480 L1 poses measured with 50 um per axis.
fn l1_pool() -> InformationPool {
    let (model, poses) = l1_poses(480, 3);
    let (j, names) = design_jacobian(&model, &poses, 50e-6, false, &l1_options()).unwrap();
    InformationPool::from_grouped_rows(&j, 3, names).unwrap()
}

fn random_best(pool: &InformationPool, k: usize, n: usize, c: Criterion, seed: u64) -> (f64, usize) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut idx: Vec<usize> = (0..pool.len()).collect();
    let mut best = f64::INFINITY;
    let mut singular = 0;
    for _ in 0..n {
        for i in 0..k {
            let j = rng.random_range(i..idx.len());
            idx.swap(i, j);
        }
        let l = pool.loss(&idx[..k], c);
        if !l.is_finite() {
            singular += 1;
        }
        best = best.min(l);
    }
    (best, singular)
}

#[test]
fn chosen_30_of_480_beat_the_best_of_1000_random_subsets() {
    let pool = l1_pool();
    assert_eq!(pool.len(), 480);
    assert_eq!(pool.n_params(), 21);
    let all: Vec<usize> = (0..pool.len()).collect();
    for c in [Criterion::D, Criterion::A, Criterion::K, Criterion::N] {
        let t = std::time::Instant::now();
        let sel = select(&pool, &all, 30, &SelectionSettings { criterion: c, ..Default::default() }).unwrap();
        let dt = t.elapsed().as_secs_f64();
        let (best_random, singular) = random_best(&pool, 30, 1000, c, 17);
        eprintln!(
            "{c}: chosen {:.5} (greedy {:.5}), best of 1000 random {:.5} ({singular} singular); {dt:.2} s (debug build)",
            c.value(sel.loss),
            c.value(sel.greedy_loss),
            c.value(best_random)
        );
        assert_eq!(sel.chosen.len(), 30);
        assert!(sel.loss < best_random, "{c}: chosen loss {} not below the best random {}", sel.loss, best_random);
        assert!(sel.loss <= sel.greedy_loss + 1e-12 * sel.greedy_loss.abs());
    }
}

#[test]
fn downdated_losses_equal_recomputed_ones_and_the_curve_ends_at_the_rank_limit() {
    let pool = l1_pool();
    let all: Vec<usize> = (0..pool.len()).collect();
    for c in [Criterion::D, Criterion::A] {
        let h = greedy_deletion(&pool, &all, 0, c, 8).unwrap();
        assert!(h.reached_rank_limit);
        for count in [400, 200, 60, 30, h.minimum_count] {
            let sub = h.subset_at(count).unwrap();
            assert_eq!(sub.len(), count);
            let exact = pool.loss(&sub, c);
            let recorded = h.loss_at(count).unwrap();
            assert!((exact - recorded).abs() <= 1e-8 * exact.abs().max(1.0), "{c} at {count}: {recorded} vs {exact}");
        }
        // The minimum: full rank, and removing any one pose loses it.
        let min = h.subset_at(h.minimum_count).unwrap();
        assert!(pool.loss(&min, c).is_finite());
        for k in 0..min.len() {
            let mut s = min.clone();
            s.remove(k);
            assert!(pool.loss(&s, c).is_infinite(), "{c}: {} poses without pose {k} keep full rank", s.len());
        }
        // 21 parameters, 3 rows per pose: at least 7 poses.
        assert!(h.minimum_count >= 7, "{}", h.minimum_count);
        eprintln!("{c}: minimum full-rank count {}", h.minimum_count);
        // The criterion degrades monotonically along the deletion.
        let curve = h.curve();
        for w in curve.windows(2) {
            let (a, b) = (w[0].1, w[1].1);
            match c {
                Criterion::D => assert!(b <= a + 1e-9),
                _ => assert!(b >= a - 1e-9 * a.abs()),
            }
        }
    }
}

#[test]
fn exchange_ends_one_swap_optimal_and_never_worsens() {
    let pool = l1_pool();
    let all: Vec<usize> = (0..120).collect();
    let start: Vec<usize> = (0..40).step_by(2).collect();
    let out = exchange(&pool, &start, &all, Criterion::D, 100, 8).unwrap();
    assert!(out.loss_after <= out.loss_before);
    let set = out.chosen.clone();
    let base = pool.loss(&set, Criterion::D);
    for pos in 0..set.len() {
        for &j in all.iter().filter(|j| !set.contains(j)) {
            let mut s = set.clone();
            s[pos] = j;
            assert!(pool.loss(&s, Criterion::D) >= base - 1e-9 * base.abs(), "swap {pos} -> {j} improves");
        }
    }
}

/// A force-sensor-like regressor (six rows per pose, ten parameters): the same selection code
/// works on row blocks, on grouped rows and on per-pose information matrices.
#[test]
fn selection_is_independent_of_the_regressor_kind() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let p = 10;
    let blocks: Vec<DMatrix<f64>> =
        (0..60).map(|_| DMatrix::from_fn(6, p, |_, _| rng.random_range(-1.0..1.0))).collect();
    let names: Vec<String> = (0..p).map(|i| format!("u{i}")).collect();
    let a = InformationPool::from_blocks(&blocks, names.clone()).unwrap();
    let stacked = DMatrix::from_fn(6 * 60, p, |r, c| blocks[r / 6][(r % 6, c)]);
    let b = InformationPool::from_grouped_rows(&stacked, 6, names.clone()).unwrap();
    let infos: Vec<DMatrix<f64>> = blocks.iter().map(|x| x.transpose() * x).collect();
    let c = InformationPool::from_information(&infos, names).unwrap();
    let all: Vec<usize> = (0..60).collect();
    let s = SelectionSettings::default();
    let sa = select(&a, &all, 12, &s).unwrap();
    let sb = select(&b, &all, 12, &s).unwrap();
    let sc = select(&c, &all, 12, &s).unwrap();
    assert_eq!(sa.chosen, sb.chosen);
    assert!((sa.loss - sc.loss).abs() < 1e-8 * sa.loss.abs().max(1.0), "{} vs {}", sa.loss, sc.loss);
    // Six rows per pose and ten parameters: two poses suffice for full rank.
    assert_eq!(sa.history.minimum_count, 2);
}

#[test]
fn prediction_with_isotropic_noise_is_the_inverse_information() {
    let (model, poses) = l1_poses(60, 9);
    let sigma = 30e-6;
    let covs = vec![Matrix3::identity() * sigma * sigma; poses.len()];
    let kp = kinematic_pool(&model, &poses, &covs, &l1_options()).unwrap();
    let chosen: Vec<usize> = (0..40).collect();
    let val: Vec<usize> = (40..60).collect();
    let pred = predict(&kp, &chosen, &val).unwrap();
    let f = kp.pool.information(&chosen);
    let inv = f.clone().try_inverse().unwrap();
    for (i, s) in pred.std_si.iter().enumerate() {
        let want = inv[(i, i)].sqrt() * kp.scales[i];
        assert!((s - want).abs() < 1e-6 * want, "{}: {s} vs {want}", pred.names[i]);
        assert!((s - pred.std_optimal_si[i]).abs() < 1e-6 * want);
    }
    assert!(pred.heldout_rms_mm > 0.0 && (pred.heldout_rms_mm - pred.heldout_rms_optimal_mm).abs() < 1e-9);
    let summary = CriteriaSummary::of(&f).unwrap();
    assert_eq!(summary.rank, 21);
}
