//! Candidate sites of one exemplar: its fields at this level and the fill and feature sites
//! with their noise and relief.

use super::super::field::{layout_lowpass, lowpass};
use super::super::relief::{Relief, WindowEnergy};
use super::super::{PreparedExemplar, RefineParams};
use super::{ExFields, NOISE_LEVELS, Site};
use crate::features::FeatureKind;

/// One exemplar's fields, fill sites (a regular grid) and feature sites (along its networks).
pub(super) fn exemplar_sites(
    ei: usize,
    e: &PreparedExemplar,
    params: &RefineParams,
) -> (ExFields, Vec<Site>, Vec<Site>) {
    let p = params.patch_size;
    let margin = (p as f32 * std::f32::consts::FRAC_1_SQRT_2).ceil() + 2.0;
    let lp = params.lowpass_factor();
    let (mid_lo, mid_hi) = params.mid_band();
    let hts = &e.heights;
    let band = hts.minus(&layout_lowpass(hts, lp));
    let form = lowpass(hts, mid_hi);
    let mid = lowpass(hts, mid_lo).minus(&form);
    let l2 = lowpass(hts, 2);
    let l4 = lowpass(hts, 4);
    let l8 = lowpass(hts, 8);
    let energies = [
        WindowEnergy::new(&hts.minus(&l2)),
        WindowEnergy::new(&l2.minus(&l4)),
        WindowEnergy::new(&l4.minus(&l8)),
    ];
    let relief = Relief::new(&form, p);
    let noise_at = |c: [f32; 2]| {
        let (cx, cy) = (c[0].round() as usize, c[1].round() as usize);
        let (x0, y0) = (cx.saturating_sub(p / 2), cy.saturating_sub(p / 2));
        let (x1, y1) = ((x0 + p).min(hts.w), (y0 + p).min(hts.h));
        let mut out = [0.0f32; NOISE_LEVELS];
        for (o, en) in out.iter_mut().zip(&energies) {
            *o = (en.mean(x0, y0, x1, y1) + 1e-6).ln() as f32;
        }
        out
    };
    let inside = |c: [f32; 2]| {
        c[0] >= margin
            && c[1] >= margin
            && c[0] <= hts.w as f32 - 1.0 - margin
            && c[1] <= hts.h as f32 - 1.0 - margin
    };
    // Fill sites: a regular grid, pitch chosen to stay under the per-exemplar budget.
    let mut fill = Vec::new();
    let span = [hts.w as f32 - 2.0 * margin, hts.h as f32 - 2.0 * margin];
    if span[0] > 0.0 && span[1] > 0.0 {
        let area = f64::from(span[0]) * f64::from(span[1]);
        let pitch = (area / params.sites_per_exemplar.max(1) as f64)
            .sqrt()
            .max(params.patch_size as f64 / 8.0) as f32;
        let mut y = margin;
        while y <= hts.h as f32 - 1.0 - margin {
            let mut x = margin;
            while x <= hts.w as f32 - 1.0 - margin {
                let c = [x.round(), y.round()];
                fill.push(Site {
                    ex: ei,
                    c,
                    dir: [1.0, 0.0],
                    kind: None,
                    noise: noise_at(c),
                    relief: relief.at(c),
                });
                x += pitch;
            }
            y += pitch;
        }
    }
    // Feature sites: points along the exemplar's polylines.
    let mut feat = Vec::new();
    let step = (p as f32 / 4.0).max(2.0);
    for line in &e.features {
        let pts = &line.points;
        let mut since = step;
        for i in 1..pts.len().saturating_sub(1) {
            let seg = (pts[i][0] - pts[i - 1][0]).hypot(pts[i][1] - pts[i - 1][1]);
            since += seg;
            if since < step || !inside(pts[i]) {
                continue;
            }
            let d = [pts[i + 1][0] - pts[i - 1][0], pts[i + 1][1] - pts[i - 1][1]];
            let len = d[0].hypot(d[1]);
            if len <= 0.0 {
                continue;
            }
            since = 0.0;
            let c = [pts[i][0].round(), pts[i][1].round()];
            feat.push(Site {
                ex: ei,
                c,
                dir: [d[0] / len, d[1] / len],
                kind: Some(line.kind),
                noise: noise_at(c),
                relief: relief.at(c),
            });
        }
    }
    // Keep at most the budget per kind, evenly spread over the network.
    let cap = params.feature_sites_per_exemplar.max(1);
    let mut kept = Vec::new();
    for kind in [FeatureKind::Ridge, FeatureKind::Valley] {
        let of: Vec<Site> = feat
            .iter()
            .filter(|s| s.kind == Some(kind))
            .copied()
            .collect();
        let stride = of.len().div_ceil(cap).max(1);
        kept.extend(of.into_iter().step_by(stride));
    }
    (ExFields { band, mid }, fill, kept)
}
