//! The target's physics in the hand-eye chain over seeds: per seed, a simulated eye-to-hand
//! recording (`ferrocal_datasets::handeye::sim`) with the given roll radius and print aspect,
//! the selection on the training images (`ferrocal_calib::handeye::physics`), what it found,
//! the fitted sags and print scale, and the held-out chain RMS without and with them. With
//! `--flat` the target is flat and printed to scale (nothing to find: counts false claims).
//!
//! `cargo run --release --offline -p ferrocal-datasets --example handeye_physics_study -- --seeds 10
//! [--first 0] [--train 24] [--test 12] [--radius-m 16] [--aspect 1.003] [--flat] [--eye-in-hand]`
//!
//! The bending is a cylinder (lengths kept along the arc), not the chain's quadratic model; the
//! print aspect is the chain's own model family.

use ferrocal_calib::handeye::physics::{select_chain_physics, PhysicsOptions};
use ferrocal_calib::handeye::{calibrate_hand_eye, HandEyeOptions, Mount};
use ferrocal_datasets::handeye::sim::{simulate_hand_eye, HandEyeSimConfig};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |name: &str| args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).cloned();
    let num = |name: &str, default: f64| get(name).map_or(default, |v| v.parse().expect("a number"));
    let seeds = num("--seeds", 10.0) as u64;
    let first = num("--first", 0.0) as u64;
    let flat = args.iter().any(|a| a == "--flat");
    let mount = if args.iter().any(|a| a == "--eye-in-hand") { Mount::EyeInHand } else { Mount::EyeToHand };
    let config = HandEyeSimConfig {
        n_train: num("--train", 24.0) as usize,
        n_test: num("--test", 12.0) as usize,
        roll_radius_m: (!flat).then(|| num("--radius-m", 16.0)),
        print_aspect: if flat { 1.0 } else { num("--aspect", 1.003) },
        ..HandEyeSimConfig::default_for(mount)
    };
    let base = HandEyeOptions { fit_target_scale: true, ..HandEyeOptions::default() };
    println!(
        "{} cell, {} training / {} held-out images, roll radius {:?} m, print aspect {}",
        mount.name(),
        config.n_train,
        config.n_test,
        config.roll_radius_m,
        config.print_aspect
    );
    println!("seed | found | bowl / saddle / twist (mm) | e_x (ppm) | held-out flat -> with (px)");
    let (mut improved, mut claims) = (0, 0);
    for seed in first..first + seeds {
        let (data, _) = simulate_hand_eye(&config, seed).expect("simulation");
        let report = select_chain_physics(&data, &base, &PhysicsOptions::default()).expect("selection");
        let flat_fit = calibrate_hand_eye(&data, &base).expect("flat fit");
        let fit = calibrate_hand_eye(&data, &report.chosen.options(&base)).expect("fit");
        let found: Vec<&str> = report.findings.iter().map(|f| f.effect.as_str()).collect();
        claims += usize::from(!found.is_empty());
        let (b, a) = (flat_fit.figures.heldout_rms_px.unwrap(), fit.figures.heldout_rms_px.unwrap());
        improved += usize::from(a < b);
        let shape = fit.target_form.filter(|f| f.deformation.shape_free).map_or("-".into(), |f| {
            let s = f.deformation.shape_m;
            format!("{:.3} / {:.3} / {:.3}", s[0] * 1e3, s[1] * 1e3, s[2] * 1e3)
        });
        let e_x = fit.target_form.filter(|f| f.deformation.scale_free).map_or("-".into(), |f| {
            format!("{:.0} +- {:.0}", f.deformation.scale[0] * 1e6, f.scale_x_std.unwrap_or(f64::NAN) * 1e6)
        });
        println!("{seed} | {found:?} | {shape} | {e_x} | {b:.4} -> {a:.4}");
    }
    println!("{claims} of {seeds} seeds with a finding; held-out chain RMS lower on {improved} of {seeds}");
}
