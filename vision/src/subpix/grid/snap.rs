//! The initial line placed on the strongest gradient across its segments ([`snap_line`]).

use super::*;

/// Moves the initial line onto the strongest gradient along profiles across each segment
/// (a few pixels either way), so that the band of the first fit contains the edge even when
/// the initial corners are off by several pixels (e.g. predicted through a homography).
pub(super) fn snap_line(img: &GrayF32, coords: &Coords, job: &LineJob, state: &mut LineState, options: &RefineOptions) {
    let n = state.normal();
    let t = state.tangent();
    let mut pts: Vec<(f64, f64, f64)> = Vec::new();
    for seg in &job.segments {
        let ta = t.dot(&(seg.a - job.origin));
        let tb = t.dot(&(seg.b - job.origin));
        let (mut lo, mut hi) = (ta.min(tb), ta.max(tb));
        let len = hi - lo;
        lo += 0.25 * len;
        hi -= 0.25 * len;
        if let Some(l) = job.t_limit {
            lo = lo.max(-l);
            hi = hi.min(l);
        }
        if hi - lo < 2.0 {
            continue;
        }
        let reach = (0.3 * seg.room_px).clamp(1.5, 6.0);
        let reach = options.max_band_px.map_or(reach, |m| reach.min(m));
        for k in 0..5 {
            let tt = lo + (hi - lo) * (k as f64 + 0.5) / 5.0;
            let steps = (reach / 0.5).round() as i32;
            let mut prof = Vec::with_capacity(2 * steps as usize + 1);
            for m in -steps..=steps {
                let u = state.d + m as f64 * 0.5;
                let mut v = 0.0;
                let mut ok = true;
                for dt in [-1.0, 0.0, 1.0] {
                    let q = job.origin + t * (tt + dt) + n * u;
                    match coords.to_pixel(q) {
                        Some(p)
                            if p.x >= 0.0
                                && p.y >= 0.0
                                && p.x <= (img.width - 1) as f64
                                && p.y <= (img.height - 1) as f64 =>
                        {
                            v += img.bilinear(p.x, p.y)
                        }
                        _ => ok = false,
                    }
                }
                if !ok {
                    prof.clear();
                    break;
                }
                prof.push(v / 3.0);
            }
            if prof.len() < 5 {
                continue;
            }
            let mut best = (0usize, 0.0f64);
            for i in 1..prof.len() - 1 {
                let g = (prof[i + 1] - prof[i - 1]).abs();
                if g > best.1 {
                    best = (i, g);
                }
            }
            let i = best.0;
            if i == 0 {
                continue;
            }
            // Parabolic peak of |gradient|.
            let g = |j: usize| (prof[(j + 1).min(prof.len() - 1)] - prof[j.saturating_sub(1)]).abs();
            let (gm, g0, gp) = (g(i - 1), g(i), g(i + 1));
            let den = gm - 2.0 * g0 + gp;
            let off = if den < 0.0 { (0.5 * (gm - gp) / den).clamp(-0.5, 0.5) } else { 0.0 };
            let u = state.d + (i as f64 - steps as f64 + off) * 0.5;
            pts.push((tt, u, best.1));
        }
    }
    if pts.len() < 3 {
        return;
    }
    let gmax = pts.iter().map(|p| p.2).fold(0.0, f64::max);
    pts.retain(|p| p.2 >= 0.3 * gmax);
    if pts.len() < 3 {
        return;
    }
    let fit = |pts: &[(f64, f64, f64)]| -> Option<(f64, f64)> {
        let n = pts.len() as f64;
        let (st, su) = pts.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
        let (mt, mu) = (st / n, su / n);
        let stt: f64 = pts.iter().map(|p| (p.0 - mt).powi(2)).sum();
        let stu: f64 = pts.iter().map(|p| (p.0 - mt) * (p.1 - mu)).sum();
        let m = if stt > 1e-9 { stu / stt } else { 0.0 };
        Some((mu - m * mt, m))
    };
    let Some((d0, m)) = fit(&pts) else { return };
    let kept: Vec<(f64, f64, f64)> = pts.iter().copied().filter(|p| (p.1 - d0 - m * p.0).abs() < 1.0).collect();
    let (d0, m) = if kept.len() >= 3 { fit(&kept).unwrap_or((d0, m)) } else { (d0, m) };
    if m.abs() > 0.2 {
        return;
    }
    let nn = (n - t * m) / (1.0 + m * m).sqrt();
    state.phi = nn.y.atan2(nn.x);
    state.d = d0 / (1.0 + m * m).sqrt();
}
