//! The octaves the exemplars do not measure: below a few of its own cells a DEM holds no relief
//! (an 80 m DEM brought to 10 m cells is interpolation there), so the finest level's land is
//! completed with the calibrated procedural detail (`terrasketch-detail`) in that band only,
//! after the cell size of the exemplar each patch came from. See the crate's README, "Octaves
//! finer than the exemplars".

use rayon::prelude::*;
use terrasketch_detail::amplitude::gradient_at;
use terrasketch_detail::calibration::AMPLITUDE_GAIN;
use terrasketch_detail::{AmplitudeInputs, HardCells, add_band_detail, amplitude_map};

use super::field::{Field, downsample, smooth3};
use super::{Placed, PreparedExemplar, RefineInput, levels};

/// The band's top, in the source exemplar's own cells: octaves up to this spacing are added
/// whole, fading out at twice it (`add_band_detail`).
pub const BAND_TOP_NATIVE_CELLS: f32 = 2.0;

/// How fast the added detail may grow away from an anchored cell: `tan` of this slope per cell
/// (the envelope of [`envelope`]), about 20 degrees.
pub const ENVELOPE_SLOPE_TAN: f32 = 0.35;

/// Adds the band of [`BAND_TOP_NATIVE_CELLS`] to the finest level's heights `h` (north-up, side
/// `n` a multiple of 4, `cell` metres; `origin` its north-west cell in the world, column and
/// row), with the amplitude of the calibrated law times `gain` (1 = as fitted on real land)
/// from the land's own slope (mip 2) and the input's roughness. Next to `anchored` cells
/// (constraints and sinks) the added detail is squeezed into an envelope that is their
/// tolerance on them (0: they do not move) and widens by [`ENVELOPE_SLOPE_TAN`] per metre away.
/// `owner` and `placed` say which exemplar each cell came from.
#[allow(clippy::too_many_arguments)]
pub(super) fn add_fine_band(
    h: &mut Field,
    input: &RefineInput,
    anchored: &[(usize, f32, f32)],
    owner: &[u32],
    placed: &[Placed],
    exemplars: &[PreparedExemplar],
    cell: f64,
    origin: [i64; 2],
    seed: u64,
    gain: f32,
) {
    let n = h.w;
    let m = n / 4;
    if !gain.is_finite()
        || gain <= 0.0
        || h.h != n
        || !n.is_multiple_of(4)
        || m < 2
        || owner.len() != n * n
    {
        return;
    }
    // Level-2 maps (block means), row 0 = south as the detail crate has them.
    let mip2 = south_up(&downsample(h, 4));
    let roughness = match input.roughness.as_deref() {
        Some(r) if r.len() == n * n => south_up(&levels::field_at(r, n, 2)),
        _ => vec![0.5; m * m],
    };
    let coarsest = exemplars
        .iter()
        .map(|e| e.native_cell_m)
        .fold(cell, f64::max) as f32;
    // A cell without owner (`NO_OWNER` indexes no patch) takes the coarsest exemplar's cells.
    let native = |o: &u32| -> f32 {
        placed
            .get(*o as usize)
            .and_then(|p| exemplars.get(p.ex))
            .map_or(coarsest, |e| e.native_cell_m.max(cell) as f32)
    };
    // The band's top per block, smoothed so that it changes over a few blocks at a seam.
    let top_full = Field::new(
        n,
        n,
        owner
            .par_iter()
            .map(|o| BAND_TOP_NATIVE_CELLS * native(o))
            .collect(),
    );
    let top = south_up(&smooth3(&downsample(&top_full, 4)));
    drop(top_full);
    let c = cell as f32;
    let mut amp = amplitude_map(&AmplitudeInputs {
        m,
        cell_m: [4.0 * c; 2],
        heights: &mip2,
        roughness: &roughness,
        roughness_side: m,
        hard: HardCells::Counts(&vec![0; m * m]),
    });
    let scale = gain / AMPLITUDE_GAIN;
    amp.iter_mut().for_each(|a| *a *= scale);
    let mut detail = vec![0.0f32; n * n];
    // World position of the south-west corner, y growing north from the world's north edge.
    let origin_m = [origin[0] as f32 * c, -((origin[1] as f32 + n as f32) * c)];
    let slope: Vec<[f32; 2]> = (0..m * m)
        .map(|i| gradient_at(&mip2, m, [4.0 * c; 2], i % m, i / m))
        .collect();
    add_band_detail(&mut detail, n, c, origin_m, &amp, &top, &slope, seed);
    let env = envelope(n, anchored, ENVELOPE_SLOPE_TAN * c);
    h.v.par_chunks_mut(n).enumerate().for_each(|(r, row)| {
        let south = &detail[(n - 1 - r) * n..(n - r) * n];
        let env = &env[r * n..(r + 1) * n];
        for ((v, &d), &e) in row.iter_mut().zip(south).zip(env) {
            *v += squeeze(d, e);
        }
    });
}

/// `d` brought smoothly under `e` in magnitude: `d e / sqrt(e^2 + d^2)`, `d` itself far from
/// any anchored cell (`e` infinite) and 0 on an exact one (`e = 0`).
fn squeeze(d: f32, e: f32) -> f32 {
    if e.is_infinite() {
        d
    } else if e <= 0.0 {
        0.0
    } else {
        d * e / (e * e + d * d).sqrt()
    }
}

/// The detail envelope (north-up, `n x n`): the least over anchored cells `a` of
/// `tol_a + step * dist(x, a)`, distances in cells by the two-pass chamfer transform (1 along
/// rows and columns, sqrt 2 across); infinite with no anchored cell.
fn envelope(n: usize, anchored: &[(usize, f32, f32)], step: f32) -> Vec<f32> {
    let mut e = vec![f32::INFINITY; n * n];
    for &(i, _, tol) in anchored {
        e[i] = e[i].min(tol.max(0.0));
    }
    if anchored.is_empty() {
        return e;
    }
    let diag = step * std::f32::consts::SQRT_2;
    for y in 0..n {
        for x in 0..n {
            let mut v = e[y * n + x];
            if x > 0 {
                v = v.min(e[y * n + x - 1] + step);
            }
            if y > 0 {
                v = v.min(e[(y - 1) * n + x] + step);
                if x > 0 {
                    v = v.min(e[(y - 1) * n + x - 1] + diag);
                }
                if x + 1 < n {
                    v = v.min(e[(y - 1) * n + x + 1] + diag);
                }
            }
            e[y * n + x] = v;
        }
    }
    for y in (0..n).rev() {
        for x in (0..n).rev() {
            let mut v = e[y * n + x];
            if x + 1 < n {
                v = v.min(e[y * n + x + 1] + step);
            }
            if y + 1 < n {
                v = v.min(e[(y + 1) * n + x] + step);
                if x + 1 < n {
                    v = v.min(e[(y + 1) * n + x + 1] + diag);
                }
                if x > 0 {
                    v = v.min(e[(y + 1) * n + x - 1] + diag);
                }
            }
            e[y * n + x] = v;
        }
    }
    e
}

/// The rows of `f` from south to north (the detail crate's order).
fn south_up(f: &Field) -> Vec<f32> {
    f.v.chunks(f.w.max(1)).rev().flatten().copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_envelope_grows_from_each_tolerance_by_its_step() {
        let n = 9;
        let e = envelope(n, &[(4 * n + 4, 0.0, 1.0), (0, 0.0, 0.0)], 2.0);
        assert_eq!(e[4 * n + 4], 1.0);
        assert_eq!(e[4 * n + 7], 7.0);
        assert!((e[5 * n + 5] - (1.0 + 2.0 * std::f32::consts::SQRT_2)).abs() < 1e-6);
        assert_eq!(e[0], 0.0);
        assert_eq!(e[1], 2.0);
        assert!(envelope(n, &[], 2.0).iter().all(|v| v.is_infinite()));
    }

    #[test]
    fn squeezed_detail_stays_inside_its_envelope() {
        for d in [-50.0f32, -3.0, -0.1, 0.0, 0.2, 4.0, 80.0] {
            assert_eq!(squeeze(d, f32::INFINITY), d);
            assert_eq!(squeeze(d, 0.0), 0.0);
            for e in [0.5f32, 2.0, 10.0] {
                let s = squeeze(d, e);
                assert!(
                    s.abs() < e && s.signum() * d.signum() >= 0.0,
                    "{d} in {e}: {s}"
                );
            }
        }
        // Far inside a wide envelope the detail is nearly itself.
        assert!((squeeze(1.0, 100.0) - 1.0).abs() < 1e-4);
    }
}
