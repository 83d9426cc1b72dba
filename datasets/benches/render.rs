//! Renders a 5 MP (2448 x 2048) image of the Gantry-Tau plate filling most of the frame, with
//! lens distortion, blur, vignetting, uneven light and noise on.
//!
//! Run: `cargo bench -p ferrocal-datasets --bench render`.

use criterion::{criterion_group, criterion_main, Criterion};
use ferrocal_datasets::render::{Illumination, Psf, RenderConfig, Renderer, TargetConfig};
use ferrocal_vision::camera::{CameraModel, Distortion, ImageSize, Intrinsics};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

fn scene() -> (Renderer, Isometry3<f64>) {
    // A 5 MP machine-vision camera (3.45 um pixels) with an 8 mm lens.
    let camera = CameraModel::new(
        Intrinsics { fx_px: 2318.8, fy_px: 2319.4, cx_px: 1226.3, cy_px: 1021.8 },
        Distortion::Brown5 { k1: -0.1021, k2: 0.1133, p1: 0.00031, p2: -0.00022, k3: -0.0418 },
        ImageSize { width_px: 2448, height_px: 2048 },
    )
    .expect("valid camera");
    let mut config = RenderConfig::default();
    config.optics.psf = Psf::Gaussian { sigma_px: 1.0 };
    config.scene.illumination = Illumination { gradient_x: 0.15, gradient_y: -0.05, quadratic: -0.1 };
    // 0.08 m squares and 0.03 m margins: a 0.30 m plate, about 1500 px across at 0.46 m.
    let target = TargetConfig::Plate { square_m: 0.08, margin_m: 0.03 };
    let renderer = Renderer::new(camera, &target, config).expect("valid scene");
    let face = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let tilt = UnitQuaternion::from_euler_angles(0.15, -0.25, 0.2);
    let t_cam_target = Isometry3::from_parts(Translation3::new(0.012, -0.008, 0.46), tilt * face);
    (renderer, t_cam_target)
}

fn bench_render(c: &mut Criterion) {
    let (renderer, t) = scene();
    let mut group = c.benchmark_group("render_5mp_plate");
    group.sample_size(20);
    group.bench_function("full (blur + noise, 8-bit)", |b| {
        let mut seed = 0u64;
        b.iter(|| {
            seed += 1;
            renderer.render(&t, seed).expect("renders")
        })
    });
    group.bench_function("expected charge only", |b| b.iter(|| renderer.render_expected(&t).expect("renders")));
    group.finish();
}

criterion_group!(benches, bench_render);
criterion_main!(benches);
