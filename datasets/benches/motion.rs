//! Motion identification and learning-control speed (issue [motion]): the output-error fits of a
//! 60 s record at 250 Hz (15,000 samples; the order-1 actuator model and the order-5
//! reference-to-tool model), the physical chain fit of the same record, the whole
//! identification experiment (records simulated, every model fitted and validated), and one
//! learning-control iteration (a 0.85 s trial of 212 samples: the trial run and the update), with
//! the learning matrix's construction apart.

use criterion::{criterion_group, criterion_main, Criterion};
use ferrocal_calib::motion::identify::fit_output_error;
use ferrocal_calib::motion::ilc::Ilc;
use ferrocal_calib::motion::mimo_ilc::MimoIlc;
use ferrocal_calib::motion::physical::fit_chain;
use ferrocal_datasets::motion::cell::CompliantCell;
use ferrocal_datasets::motion::cell_ilc::reference_to_tool_impulse_response;
use ferrocal_datasets::motion::cell_study::{identify_cell, CellIdentifySettings};
use ferrocal_datasets::motion::study::{identify_axis, IdentifySettings};
use ferrocal_datasets::motion::tracking::{Tracker, TrackingSettings};
use ferrocal_datasets::motion::{quintic_move, random_binary_reference, CompliantAxis, SensorNoise};

fn bench(c: &mut Criterion) {
    let axis = CompliantAxis::l1_like();
    let dt = axis.dt_s;
    let n = (60.0 / dt) as usize;
    let r = random_binary_reference(n, 1, 0.002, 1);
    let rec = axis.run(&r, SensorNoise::default(), 1).unwrap();
    let mut g = c.benchmark_group("motion");
    g.sample_size(10);
    g.bench_function("output_error_order1_60s", |b| {
        b.iter(|| fit_output_error(&r, &rec.encoder_m, 1, 1, 6, dt).unwrap())
    });
    g.bench_function("output_error_order5_60s", |b| {
        b.iter(|| fit_output_error(&r, &rec.tool_measured_m, 5, 5, 6, dt).unwrap())
    });
    let start = fit_output_error(&rec.encoder_m, &rec.tool_measured_m, 4, 4, 1, dt).unwrap().modes();
    g.bench_function("physical_chain_60s", |b| {
        b.iter(|| fit_chain(&rec.encoder_m, &rec.tool_measured_m, dt, axis.chain.m2_kg, &start).unwrap())
    });
    g.bench_function("identification_experiment_60s_30s", |b| {
        b.iter(|| identify_axis(&axis, &IdentifySettings::default()).unwrap())
    });
    let id = identify_axis(&axis, &IdentifySettings::default()).unwrap();
    let trial = 212;
    let h = id.tool_tracker.model().impulse_response(trial);
    g.bench_function("ilc_learning_matrix_212", |b| b.iter(|| Ilc::norm_optimal(&h, 1e-4).unwrap()));
    let ilc = Ilc::norm_optimal(&h, 1e-4).unwrap();
    let yd = quintic_move(trial, dt, 0.1, 0.15, 0.02);
    g.bench_function("ilc_iteration_212", |b| {
        b.iter(|| {
            let rec = axis.run(&yd, SensorNoise::default(), 2).unwrap();
            let e: Vec<f64> = yd.iter().zip(&rec.tool_measured_m).map(|(a, b)| a - b).collect();
            ilc.update(&yd, &e).unwrap()
        })
    });
    let tracker = Tracker::new(&TrackingSettings::default()).unwrap();
    let subs: Vec<f64> = (0..8).map(|j| 1e-4 * j as f64).collect();
    g.bench_function("render_blurred_1mp_frame_8_subframes", |b| b.iter(|| tracker.expose(&subs, 3).unwrap()));
    let frame = tracker.expose(&subs, 3).unwrap();
    assert_eq!(frame.width() * frame.height(), 1280 * 800);
    g.bench_function("track_1mp_frame", |b| b.iter(|| tracker.measure(&frame).unwrap()));

    // The 3-DOF cell: identification of a 60 s record (simulated, fitted, validated on 30 s) and
    // one learning trial with its 3 x 3 update (450 samples: lifted 1350 x 1350).
    let cell = CompliantCell::l1_like();
    let ids = CellIdentifySettings::default();
    g.bench_function("cell_identification_60s_30s", |b| b.iter(|| identify_cell(&cell, &ids, &|_| {}).unwrap()));
    let cid = identify_cell(&cell, &ids, &|_| {}).unwrap();
    let n = 450;
    let hm = reference_to_tool_impulse_response(&cid, n).unwrap();
    g.bench_function("cell_mimo_learning_matrix_450", |b| b.iter(|| MimoIlc::norm_optimal(&hm, 1e-4).unwrap()));
    let mimo = MimoIlc::norm_optimal(&hm, 1e-4).unwrap();
    let u: Vec<[f64; 3]> = vec![[0.0; 3]; n];
    g.bench_function("cell_ilc_iteration_450", |b| {
        b.iter(|| {
            let rec = cell.run_from([0.0; 3], &u, 1e-6, 1e-5, 2).unwrap();
            let e: Vec<[f64; 3]> = rec.tool_measured_m.iter().map(|t| [-t[0], -t[1], -t[2]]).collect();
            mimo.update(&u, &e).unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
