//! Is the camera clock's stated standard deviation honest? The tracking experiment of
//! `ferrocal motion study` (a 20 mm quintic move in 0.15 s, rendered frames with motion blur)
//! repeated over seeds, each with its own clock offset drawn from 0-40 ms; the offset estimated
//! against the track the identified chain predicts from the encoder (and, for comparison, against
//! the encoder itself). Prints each seed and the RMS of error / sigma.
//!
//! `cargo run --release -p ferrocal-datasets --example motion_sync -- [--seeds 20] [--full]
//! [--rate-ppm R] [--model chain|chain-fine|true-chain|truth] [--timing-us T]` (`--full`: the study's 1280 x 800 camera
//! instead of 640 x 400; `--model`: the track predicted by the identified chain, the true chain,
//! or the true tool samples; `--timing-us`: the stated model timing uncertainty, default the
//! study's).

use ferrocal_calib::motion::sync::SyncSettings;
use ferrocal_datasets::motion::study::{identify_axis, IdentifySettings, IlcSettings};
use ferrocal_datasets::motion::tracking::{synchronise, Tracker, TrackingSettings, MODEL_TIMING_STD_S};
use ferrocal_datasets::motion::{quintic_move, CompliantAxis, SensorNoise};
use rand::{Rng, SeedableRng};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let get = |k: &str| args.iter().position(|a| a == k).and_then(|i| args.get(i + 1)).cloned();
    let seeds: u64 = get("--seeds").map_or(Ok(20), |s| s.parse())?;
    let rate_ppm: f64 = get("--rate-ppm").map_or(Ok(0.0), |s| s.parse())?;
    let full = args.iter().any(|a| a == "--full");
    // The model whose predicted track the frames are matched to: the identified chain (default),
    // the true chain, or the true tool samples themselves.
    let model = get("--model").unwrap_or_else(|| "chain".into());
    // The stated model timing uncertainty, µs (the study's: MODEL_TIMING_STD_S).
    let timing_us: f64 = get("--timing-us").map_or(Ok(1e6 * MODEL_TIMING_STD_S), |s| s.parse())?;
    let sync = SyncSettings { model_timing_std_s: 1e-6 * timing_us, ..SyncSettings::default() };
    let axis = CompliantAxis::l1_like();
    let dt = axis.dt_s;
    let id = identify_axis(&axis, &IdentifySettings::default())?;
    let chain = id.physical_chain(axis.chain.m2_kg);
    let il = IlcSettings::default();
    let n = ((0.1 + il.move_s + 0.2) / dt).round() as usize;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(99);
    let (mut z2, mut z2_enc, mut zmax, mut sig, mut err_sum) = (0.0, 0.0, 0.0f64, Vec::new(), 0.0);
    let (mut ev, mut vv) = (0.0, 0.0);
    println!("stated model timing uncertainty {timing_us} µs");
    println!("seed  truth_ms  estimate_ms  sigma_us  error_us  z  chi2  | encoder as the model: z (error +- sigma)");
    for seed in 1..=seeds {
        let base = if full {
            TrackingSettings::default()
        } else {
            TrackingSettings { width_px: 640, height_px: 400, focal_px: 700.0, distance_m: 0.6, ..Default::default() }
        };
        let s =
            TrackingSettings { seed, clock_offset_s: rng.random_range(0.0..0.04), clock_rate_ppm: rate_ppm, ..base };
        let rec = axis.run(&quintic_move(n, dt, 0.1, il.move_s, il.distance_m), SensorNoise::default(), seed)?;
        let seq = Tracker::new(&s)?.track(&rec.tool_true_m, dt)?;
        let predicted = match model.as_str() {
            "chain" => chain.simulate(&rec.encoder_m, dt, 8),
            "true-chain" => axis.chain.simulate(&rec.encoder_m, dt, 8),
            "truth" => rec.tool_true_m.clone(),
            "chain-fine" => {
                // The encoder interpolated by a cubic spline to a quarter sample, the chain run on it.
                let sp = ferrocal_calib::motion::sync::Spline::new(&rec.encoder_m, dt);
                let fine: Vec<f64> = (0..4 * (n - 1) + 1).map(|i| sp.eval(i as f64 * dt / 4.0).0).collect();
                chain.simulate(&fine, dt / 4.0, 2).into_iter().step_by(4).collect()
            }
            m => return Err(format!("--model {m}: give chain, true-chain or truth").into()),
        };
        let (_, r) = synchronise(&seq, &s, &predicted, dt, &sync)?;
        let enc = synchronise(&seq, &s, &rec.encoder_m, dt, &sync).map(|x| x.1);
        let ze = enc.as_ref().map(|e| e.offset_z());
        let z = r.offset_z();
        z2 += z * z;
        zmax = zmax.max(z.abs());
        sig.push(r.offset_std_s);
        if let Ok(ze) = ze {
            z2_enc += ze * ze;
        }
        err_sum += r.offset_s - r.true_offset_s;
        // The frames' errors against the exposure-averaged truth, regressed on the tool's speed:
        // an error proportional to the speed is a time shift.
        for f in &seq.frames {
            let k = f.sample.clamp(1, n - 2);
            let v = (rec.tool_true_m[k + 1] - rec.tool_true_m[k - 1]) / (2.0 * dt);
            ev += (f.position_m - f.truth_mean_m) * v;
            vv += v * v;
        }
        println!(
            "{seed:4}  {:8.4}  {:11.5}  {:8.2}  {:+8.2}  {:+5.2}  {:5.2}  | {}",
            1e3 * r.true_offset_s,
            1e3 * r.offset_s,
            1e6 * r.offset_std_s,
            1e6 * (r.offset_s - r.true_offset_s),
            z,
            r.reduced_chi2,
            enc.as_ref().map_or_else(
                |e| e.to_string(),
                |e| format!(
                    "{:+.1} ({:+.1} µs +- {:.1} µs)",
                    e.offset_z(),
                    1e6 * (e.offset_s - e.true_offset_s),
                    1e6 * e.offset_std_s
                )
            )
        );
    }
    sig.sort_by(f64::total_cmp);
    println!(
        "{seeds} seeds: RMS of error / sigma {:.2} (largest |z| {:.2}), mean error {:+.2} µs, median sigma {:.2} µs; encoder as the model: RMS z {:.1}",
        (z2 / seeds as f64).sqrt(),
        zmax,
        1e6 * err_sum / seeds as f64,
        1e6 * sig[sig.len() / 2],
        (z2_enc / seeds as f64).sqrt()
    );
    println!("tracking error against the truth regressed on the tool's speed: {:+.2} µs", 1e6 * ev / vv);
    Ok(())
}
