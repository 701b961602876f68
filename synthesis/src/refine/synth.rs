//! Patch placement: feature patches along the target's ridge/valley network, then a best-first
//! fill on a lattice; each patch chosen by normalised matching costs, the best few re-ranked by
//! graph-cut seam cost, and cut into the output along the minimum seam.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use super::field::{Field, TRANSFORMS, to_exemplar, to_target, unit_hash};
use super::relief::{Relief, detail_gain};
use super::{PreparedExemplar, RefineError, RefineParams};
use crate::features::FeatureKind;

mod cut;
mod fill;
mod sites;

use sites::exemplar_sites;

/// Owner value of a cell no patch covers yet.
pub const NO_OWNER: u32 = u32::MAX;
/// Number of noise-variance levels (Tasse 2011: 3).
const NOISE_LEVELS: usize = 3;
/// Samples of the 4 x 4 shape descriptor.
const DESC: usize = 16;
/// Samples per feature profile (along and across the feature).
const PROFILE: usize = 9;

/// One exemplar's fields for this run.
pub struct ExFields {
    /// Detail: heights minus their low-pass (what patches carry).
    pub band: Field,
    /// Smoothed detail (low-pass at 4 cells minus the low-pass): descriptors and profiles.
    pub mid: Field,
}

/// A placed patch.
#[derive(Clone, Copy, Debug)]
pub struct Placed {
    /// Exemplar index.
    pub ex: usize,
    /// Transform (see `field::to_exemplar`).
    pub k: usize,
    /// Centre in the exemplar (cells).
    pub c: [f32; 2],
    /// Centre in the output (cells).
    pub p: [i32; 2],
    /// Factor on the patch's detail (see [`detail_gain`]).
    pub gain: f32,
}

/// A candidate source location (the transform is chosen separately).
#[derive(Clone, Copy)]
struct Site {
    ex: usize,
    c: [f32; 2],
    /// Feature direction (unit, exemplar frame) for feature sites.
    dir: [f32; 2],
    kind: Option<FeatureKind>,
    /// Log noise variance per level.
    noise: [f32; NOISE_LEVELS],
    /// Log RMS slope of the low-pass over the patch window (see [`Relief`]).
    relief: f32,
}

/// The synthesis state.
pub struct Synth<'a> {
    n: usize,
    half: i32,
    params: &'a RefineParams,
    ex: Vec<ExFields>,
    target_mid: Field,
    /// Relief of the target's low-pass (the layout), per patch window.
    target_relief: Relief,
    roughness: Option<&'a [f32]>,
    fill_sites: Vec<Site>,
    /// Descriptors of each fill site under each transform: `[site][k][DESC]`.
    fill_desc: Vec<[f32; DESC]>,
    feature_sites: Vec<Site>,
    /// Sorted pooled log-variances per level (for the roughness quantile).
    noise_sorted: [Vec<f32>; NOISE_LEVELS],
    /// Detail of the owning patch per cell.
    pub dout: Vec<f32>,
    /// Owning patch per cell.
    pub owner: Vec<u32>,
    /// Patches in placement order.
    pub placed: Vec<Placed>,
    /// Feature patches placed.
    pub patches_feature: usize,
    /// Candidate sites (fill, feature), before the 16 transforms.
    pub sites: (usize, usize),
    /// Fill patches placed.
    pub patches_fill: usize,
    /// Sides of the window (west, east, north, south) whose border band a later patch will
    /// cover: unfilled cells there within a noisy margin are left to it.
    open_sides: [bool; 4],
    /// Where in each exemplar the placed patches came from (see [`Reuse`]).
    reuse: Vec<Reuse>,
}

/// Patch centres taken from one exemplar so far, counted on a grid of a quarter patch: a site's
/// reuse is the count in the 3 x 3 cells around it, so that the same piece of land (and its
/// particular ridges) is not copied all over the map.
struct Reuse {
    cell: f32,
    w: usize,
    h: usize,
    counts: Vec<u32>,
}

impl Reuse {
    fn new(w: usize, h: usize, patch: usize) -> Reuse {
        let cell = (patch / 4).max(1) as f32;
        let (w, h) = (
            (w as f32 / cell).ceil() as usize + 1,
            (h as f32 / cell).ceil() as usize + 1,
        );
        Reuse {
            cell,
            w,
            h,
            counts: vec![0; w * h],
        }
    }

    fn index(&self, c: [f32; 2]) -> (usize, usize) {
        let at = |v: f32, m: usize| ((v / self.cell).max(0.0) as usize).min(m - 1);
        (at(c[0], self.w), at(c[1], self.h))
    }

    fn add(&mut self, c: [f32; 2]) {
        let (x, y) = self.index(c);
        self.counts[y * self.w + x] += 1;
    }

    fn around(&self, c: [f32; 2]) -> u32 {
        let (x, y) = self.index(c);
        let mut sum = 0;
        for yy in y.saturating_sub(1)..(y + 2).min(self.h) {
            for xx in x.saturating_sub(1)..(x + 2).min(self.w) {
                sum += self.counts[yy * self.w + xx];
            }
        }
        sum
    }
}

/// Mean of `v` in f64, sequentially (deterministic).
fn mean(v: impl Iterator<Item = f32>) -> f32 {
    let (mut s, mut c) = (0.0f64, 0usize);
    for x in v {
        s += f64::from(x);
        c += 1;
    }
    if c == 0 {
        1.0
    } else {
        ((s / c as f64) as f32).max(1e-12)
    }
}

impl<'a> Synth<'a> {
    /// Prepares per-exemplar fields, candidate sites and descriptors.
    pub fn new(
        n: usize,
        exemplars: &[PreparedExemplar],
        target_mid: Field,
        target_form: &Field,
        roughness: Option<&'a [f32]>,
        params: &'a RefineParams,
    ) -> Result<Synth<'a>, RefineError> {
        let p = params.patch_size;
        let half = (p / 2) as i32;
        let prepared: Vec<(ExFields, Vec<Site>, Vec<Site>)> = exemplars
            .par_iter()
            .enumerate()
            .map(|(ei, e)| exemplar_sites(ei, e, params))
            .collect();
        let mut ex = Vec::new();
        let (mut fill_sites, mut feature_sites) = (Vec::new(), Vec::new());
        for (f, fill, feat) in prepared {
            ex.push(f);
            fill_sites.extend(fill);
            feature_sites.extend(feat);
        }
        if fill_sites.is_empty() {
            return Err(RefineError::BadInput(format!(
                "no exemplar is large enough for {p}-cell patches at this cell size"
            )));
        }
        let offs = desc_offsets(p);
        let fill_desc: Vec<[f32; DESC]> = fill_sites
            .par_iter()
            .flat_map_iter(|s| {
                let mid = &ex[s.ex].mid;
                (0..TRANSFORMS).map(move |k| {
                    let mut d = [0.0f32; DESC];
                    for (o, &[u, v]) in d.iter_mut().zip(&offs) {
                        let (a, b) = to_exemplar(k, u, v);
                        *o = mid.sample(s.c[0] + a, s.c[1] + b);
                    }
                    d
                })
            })
            .collect();
        let noise_sorted = std::array::from_fn(|l| {
            let mut v: Vec<f32> = fill_sites.iter().map(|s| s.noise[l]).collect();
            v.sort_by(f32::total_cmp);
            v
        });
        let reuse = exemplars
            .iter()
            .map(|e| Reuse::new(e.heights.w, e.heights.h, p))
            .collect();
        Ok(Synth {
            n,
            half,
            params,
            reuse,
            ex,
            target_mid,
            target_relief: Relief::new(target_form, p),
            roughness,
            fill_sites,
            fill_desc,
            feature_sites,
            noise_sorted,
            dout: vec![0.0; n * n],
            owner: vec![NO_OWNER; n * n],
            placed: Vec::new(),
            patches_feature: 0,
            patches_fill: 0,
            sites: (0, 0),
            open_sides: [true; 4],
        })
        .map(|mut s: Synth<'a>| {
            s.sites = (s.fill_sites.len(), s.feature_sites.len());
            s
        })
    }

    /// Exemplar fields (for the merge).
    pub fn fields(&self) -> &[ExFields] {
        &self.ex
    }

    /// Weight of the noise cost: the roughness map's, when there is one; without one the
    /// relief alone sets the character (a fixed median roughness would make it uniform).
    fn noise_weight(&self) -> f32 {
        if self.roughness.is_some() {
            self.params.weights.noise
        } else {
            0.0
        }
    }

    /// Log-variances wanted at output cell `(x, y)`: the roughness's quantile of the pooled sites.
    fn wanted_noise(&self, x: i32, y: i32) -> [f32; NOISE_LEVELS] {
        let r = self.roughness.map_or(0.5, |r| {
            let i = (y.clamp(0, self.n as i32 - 1) as usize) * self.n
                + x.clamp(0, self.n as i32 - 1) as usize;
            r[i].clamp(0.0, 1.0)
        });
        std::array::from_fn(|l| {
            let s = &self.noise_sorted[l];
            s[((r * (s.len() - 1) as f32).round() as usize).min(s.len() - 1)]
        })
    }

    /// The candidate's detail at output cell `(x, y)` when centred at output `p`.
    #[inline]
    fn value(&self, pl: &Placed, x: i32, y: i32) -> f32 {
        let (a, b) = to_exemplar(pl.k, (x - pl.p[0]) as f32, (y - pl.p[1]) as f32);
        pl.gain * self.ex[pl.ex].band.sample(pl.c[0] + a, pl.c[1] + b)
    }

    /// The output window of a patch centred at `p`, clipped: `(x0, y0, x1, y1)`.
    fn window(&self, p: [i32; 2]) -> (i32, i32, i32, i32) {
        let n = self.n as i32;
        (
            (p[0] - self.half).max(0),
            (p[1] - self.half).max(0),
            (p[0] + self.half).min(n),
            (p[1] + self.half).min(n),
        )
    }

    /// A patch slot's key for the seeded jitter: its centre's world cell (see
    /// `RefineParams::origin`), so the same world position draws the same numbers in any tile.
    fn world_key(&self, p: [i32; 2]) -> u64 {
        let [ox, oy] = self.params.origin;
        let x = (i64::from(p[0]) + ox) as u32;
        let y = (i64::from(p[1]) + oy) as u32;
        (u64::from(y) << 32) | u64::from(x)
    }

    /// Places feature patches along the target's lines. Returns the number placed.
    pub fn place_features(
        &mut self,
        lines: &[super::exemplar::FeatureLine],
        cancel: &AtomicBool,
        progress: &dyn Fn(f32),
    ) -> Result<(), RefineError> {
        let spacing = (self.params.patch_size as f32 / 2.0).max(2.0);
        let mut order: Vec<&super::exemplar::FeatureLine> = lines.iter().collect();
        // Longest first (ties keep extraction order).
        order.sort_by(|a, b| {
            crate::features::polyline_length(&b.points)
                .total_cmp(&crate::features::polyline_length(&a.points))
        });
        let mut points: Vec<([i32; 2], [f32; 2], FeatureKind)> = Vec::new();
        for line in order {
            let pts = &line.points;
            let mut since = spacing / 2.0;
            for i in 1..pts.len().saturating_sub(1) {
                since += (pts[i][0] - pts[i - 1][0]).hypot(pts[i][1] - pts[i - 1][1]);
                if since < spacing {
                    continue;
                }
                let d = [pts[i + 1][0] - pts[i - 1][0], pts[i + 1][1] - pts[i - 1][1]];
                let len = d[0].hypot(d[1]);
                let p = [pts[i][0].round() as i32, pts[i][1].round() as i32];
                let near = points.iter().any(|(q, _, _)| {
                    ((q[0] - p[0]) as f32).hypot((q[1] - p[1]) as f32) < spacing * 0.75
                });
                if len <= 0.0 || near {
                    continue;
                }
                since = 0.0;
                points.push((p, [d[0] / len, d[1] / len], line.kind));
            }
        }
        let total = points.len().max(1);
        // The fill covers every cell later, so feature patches leave a noisy border band.
        self.open_sides = [true; 4];
        for (i, (p, dir, kind)) in points.into_iter().enumerate() {
            if cancel.load(Ordering::Relaxed) {
                return Err(RefineError::Cancelled);
            }
            if self.place_feature(p, dir, kind, self.world_key(p)) {
                self.patches_feature += 1;
            }
            progress((i + 1) as f32 / total as f32);
        }
        Ok(())
    }

    fn place_feature(&mut self, p: [i32; 2], dir: [f32; 2], kind: FeatureKind, slot: u64) -> bool {
        let sites: Vec<usize> = (0..self.feature_sites.len())
            .filter(|&i| self.feature_sites[i].kind == Some(kind))
            .collect();
        if sites.is_empty() {
            return false;
        }
        let step = self.params.patch_size as f32 / 10.0;
        let normal = [-dir[1], dir[0]];
        let tm = &self.target_mid;
        let (px, py) = (p[0] as f32, p[1] as f32);
        let mut tprof = [0.0f32; 2 * PROFILE];
        for j in 0..PROFILE {
            let t = (j as f32 - (PROFILE / 2) as f32) * step;
            tprof[j] = tm.sample(px + t * dir[0], py + t * dir[1]);
            tprof[PROFILE + j] = tm.sample(px + t * normal[0], py + t * normal[1]);
        }
        let want = self.wanted_noise(p[0], p[1]);
        let relief = self.target_relief.at([p[0] as f32, p[1] as f32]);
        // Costs per (site, transform): profile, angle, noise, relief.
        // Transforms that turn the candidate's feature more than 45 degrees away from the
        // target's are not considered (their angle cost alone rules them out); the profile
        // cost, the expensive term, is computed for the others only.
        let raw: Vec<(usize, usize, [f32; 4])> = sites
            .par_iter()
            .flat_map_iter(|&si| {
                let s = self.feature_sites[si];
                let band = &self.ex[s.ex].mid;
                let noise = noise_cost(&s.noise, &want);
                let rel = (s.relief - relief).abs();
                (0..TRANSFORMS).filter_map(move |k| {
                    let (dx, dy) = to_target(k, s.dir[0], s.dir[1]);
                    let cos = (dx * dir[0] + dy * dir[1]).abs().min(1.0);
                    let angle = cos.acos() / std::f32::consts::FRAC_PI_2;
                    if angle > 0.5 {
                        return None;
                    }
                    let mut sq = 0.0f32;
                    for j in 0..PROFILE {
                        let t = (j as f32 - (PROFILE / 2) as f32) * step;
                        for (axis, off) in [(dir, 0), (normal, PROFILE)] {
                            let (a, b) = to_exemplar(k, t * axis[0], t * axis[1]);
                            let d = band.sample(s.c[0] + a, s.c[1] + b) - tprof[off + j];
                            sq += d * d;
                        }
                    }
                    Some((
                        si,
                        k,
                        [(sq / (2 * PROFILE) as f32).sqrt(), angle, noise, rel],
                    ))
                })
            })
            .collect();
        let norms: [f32; 4] = std::array::from_fn(|t| mean(raw.iter().map(|c| c.2[t])));
        let w = &self.params.weights;
        let weights = [
            w.feature_profile,
            w.feature_angle,
            self.noise_weight(),
            w.relief,
        ];
        let cands: Vec<(usize, usize, f32)> = raw
            .iter()
            .map(|&(si, k, c)| {
                let cost: f32 = (0..4).map(|t| weights[t] * c[t] / norms[t]).sum();
                (si, k, cost)
            })
            .collect();
        self.choose_and_apply(p, &cands, true, slot, true)
    }

    /// Round 2 (overlap) and round 3 (graph cut) on the best candidates, then cuts the winner in.
    /// `cands`: (site, transform, normalised cost).
    fn choose_and_apply(
        &mut self,
        p: [i32; 2],
        cands: &[(usize, usize, f32)],
        feature: bool,
        slot: u64,
        core: bool,
    ) -> bool {
        if cands.is_empty() {
            return false;
        }
        let ranked = self.shortlist(cands, feature, slot);
        let sites = if feature {
            &self.feature_sites
        } else {
            &self.fill_sites
        };
        let relief = self.target_relief.at([p[0] as f32, p[1] as f32]);
        let make = |i: usize| {
            let (si, k, _) = cands[i];
            let s = &sites[si];
            Placed {
                ex: s.ex,
                k,
                c: s.c,
                p,
                gain: detail_gain(relief, s.relief),
            }
        };
        let (x0, y0, x1, y1) = self.window(p);
        let n = self.n as i32;
        let any_filled =
            (y0..y1).any(|y| (x0..x1).any(|x| self.owner[(y * n + x) as usize] != NO_OWNER));
        let overlap: Vec<f32> = ranked
            .par_iter()
            .map(|&(_, i)| {
                if !any_filled {
                    return 0.0;
                }
                let pl = make(i);
                let (mut sq, mut cnt) = (0.0f64, 0usize);
                for y in (y0..y1).step_by(2) {
                    for x in (x0..x1).step_by(2) {
                        let o = (y * n + x) as usize;
                        if self.owner[o] != NO_OWNER {
                            let d = self.value(&pl, x, y) - self.dout[o];
                            sq += f64::from(d * d);
                            cnt += 1;
                        }
                    }
                }
                if cnt == 0 {
                    0.0
                } else {
                    (sq / cnt as f64).sqrt() as f32
                }
            })
            .collect();
        let onorm = mean(overlap.iter().copied());
        let mut second: Vec<(f32, usize)> = ranked
            .iter()
            .zip(&overlap)
            .map(|(&(c, i), &o)| (c + self.params.weights.overlap * o / onorm, i))
            .collect();
        second.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let k2 = if any_filled {
            self.params.graphcut_candidates.clamp(1, second.len())
        } else {
            1
        };
        // One task a cut (a few costly items): a thread that finishes early takes the next.
        let cuts: Vec<(f64, Vec<bool>)> = second[..k2]
            .par_iter()
            .with_max_len(1)
            .map(|&(_, i)| self.cut(&make(i), core))
            .collect();
        let mut best = 0;
        for (j, c) in cuts.iter().enumerate() {
            if c.0 < cuts[best].0 {
                best = j;
            }
        }
        self.paste(make(second[best].1), &cuts[best].1, (x0, y0, x1, y1));
        true
    }

    /// Round 2's shortlist: the `overlap_candidates` best of `cands` by jittered cost (jitter
    /// hashed from the seed, `feature` and `slot`) as (cost, index into `cands`), best first.
    fn shortlist(
        &self,
        cands: &[(usize, usize, f32)],
        feature: bool,
        slot: u64,
    ) -> Vec<(f32, usize)> {
        let seed = self.params.seed;
        let tag = if feature { 1u64 << 40 } else { 0 } | slot;
        let jitter = self.params.jitter;
        let sites = if feature {
            &self.feature_sites
        } else {
            &self.fill_sites
        };
        // The reuse factor is a site's, whatever the transform: once per site.
        let w_reuse = self.params.weights.reuse;
        let reuse: Vec<f32> = if w_reuse > 0.0 && !self.placed.is_empty() {
            sites
                .iter()
                .map(|s| 1.0 + w_reuse * self.reuse[s.ex].around(s.c) as f32)
                .collect()
        } else {
            vec![1.0; sites.len()]
        };
        let mut ranked: Vec<(f32, usize)> = cands
            .par_iter()
            .enumerate()
            .map(|(i, c)| {
                let jittered = c.2 * (1.0 + jitter * unit_hash(seed, tag, i as u64));
                (jittered * reuse[c.0], i)
            })
            .collect();
        let k1 = self.params.overlap_candidates.clamp(1, ranked.len());
        let order = |a: &(f32, usize), b: &(f32, usize)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
        // The k1 best of each chunk in parallel, then of their union: the order is total (ties
        // go by index), so the k1 best are the same set as from one selection over all.
        let chunk = ranked
            .len()
            .div_ceil(2 * rayon::current_num_threads())
            .max(k1);
        let mut ranked: Vec<(f32, usize)> = ranked
            .par_chunks_mut(chunk)
            .flat_map_iter(|c| {
                let m = k1.min(c.len());
                c.select_nth_unstable_by(m - 1, order);
                c[..m].to_vec()
            })
            .collect();
        ranked.select_nth_unstable_by(k1 - 1, order);
        ranked.truncate(k1);
        ranked.sort_by(order);
        ranked
    }

    /// Places `pl` on the cells of the window `(x0, y0, x1, y1)` where `take` (row-major over
    /// the window) is set: they get its values and its new owner id.
    fn paste(&mut self, pl: Placed, take: &[bool], (x0, y0, x1, y1): (i32, i32, i32, i32)) {
        let n = self.n as i32;
        let id = self.placed.len() as u32;
        let ww = (x1 - x0) as usize;
        for y in y0..y1 {
            for x in x0..x1 {
                if take[(y - y0) as usize * ww + (x - x0) as usize] {
                    let o = (y * n + x) as usize;
                    self.owner[o] = id;
                    self.dout[o] = self.value(&pl, x, y);
                }
            }
        }
        self.reuse[pl.ex].add(pl.c);
        self.placed.push(pl);
    }
}

/// RMS difference of log-variances.
fn noise_cost(a: &[f32; NOISE_LEVELS], b: &[f32; NOISE_LEVELS]) -> f32 {
    let s: f32 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    (s / NOISE_LEVELS as f32).sqrt()
}

/// Offsets of the 4 x 4 descriptor samples, covering the central 3/4 of a patch.
fn desc_offsets(p: usize) -> [[f32; 2]; DESC] {
    let span = p as f32 * 0.75;
    std::array::from_fn(|i| {
        let (ix, iy) = ((i % 4) as f32, (i / 4) as f32);
        [
            ((ix + 0.5) / 4.0 - 0.5) * span,
            ((iy + 0.5) / 4.0 - 0.5) * span,
        ]
    })
}
