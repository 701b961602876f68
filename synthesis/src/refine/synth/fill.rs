//! The best-first fill: patch centres on a lattice, the next slot the one most filled, each
//! patch chosen by normalised matching costs.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use super::super::RefineError;
use super::super::field::{TRANSFORMS, unit_hash};
use super::{DESC, NO_OWNER, Synth, desc_offsets, mean, noise_cost};

impl Synth<'_> {
    /// Fills the rest best-first on a lattice of patch centres (Criminisi-style priority:
    /// filled fraction of the window plus a data term from the target's detail gradient).
    pub fn fill(&mut self, cancel: &AtomicBool, progress: &dyn Fn(f32)) -> Result<(), RefineError> {
        let n = self.n as i32;
        let p = self.params.patch_size as i32;
        let step = (p - (p / 4).max(1)).max(1);
        let phase = (unit_hash(self.params.seed, 0xF111, 0) * step.min(self.half) as f32) as i32;
        // The lattice is anchored in the world (`params.origin`), so overlapping tiles put
        // their patch centres on the same world cells.
        let axis_from = |origin: i64| {
            let mut c = (i64::from(phase) - origin).rem_euclid(i64::from(step)) as i32;
            if c > self.half {
                // The first centre would leave the first cells uncovered.
                c -= step;
            }
            let mut axis = Vec::new();
            loop {
                axis.push(c);
                if c + self.half >= n {
                    break;
                }
                c += step;
            }
            axis
        };
        let [ox, oy] = self.params.origin;
        let (axis_x, axis_y) = (axis_from(ox), axis_from(oy));
        let slots: Vec<[i32; 2]> = axis_y
            .iter()
            .flat_map(|&y| axis_x.iter().map(move |&x| [x, y]))
            .collect();
        // Data term: mean |grad| of the target's mid band over the window, scaled to [0, 1].
        let tm = &self.target_mid;
        let data: Vec<f32> = slots
            .par_iter()
            .map(|&s| {
                let (x0, y0, x1, y1) = self.window(s);
                let mut acc = 0.0f64;
                for y in y0..y1 {
                    for x in x0..x1 {
                        let gx = tm.at(x as isize + 1, y as isize) - tm.at(x as isize, y as isize);
                        let gy = tm.at(x as isize, y as isize + 1) - tm.at(x as isize, y as isize);
                        acc += f64::from(gx.hypot(gy));
                    }
                }
                (acc / ((x1 - x0) * (y1 - y0)).max(1) as f64) as f32
            })
            .collect();
        let dmax = data.iter().cloned().fold(0.0f32, f32::max).max(1e-12);
        let mut done = vec![false; slots.len()];
        let filled_frac = |me: &Synth, s: [i32; 2]| {
            let (x0, y0, x1, y1) = me.window(s);
            let mut f = 0usize;
            for y in y0..y1 {
                for x in x0..x1 {
                    f += usize::from(me.owner[(y * n + x) as usize] != NO_OWNER);
                }
            }
            f as f32 / ((x1 - x0) * (y1 - y0)).max(1) as f32
        };
        let mut conf: Vec<f32> = slots.iter().map(|&s| filled_frac(self, s)).collect();
        let total = slots.len();
        for iter in 0..total {
            if cancel.load(Ordering::Relaxed) {
                return Err(RefineError::Cancelled);
            }
            let mut best: Option<(usize, f32)> = None;
            for i in 0..slots.len() {
                if done[i] {
                    continue;
                }
                if conf[i] >= 1.0 {
                    done[i] = true;
                    continue;
                }
                let pr = conf[i] + 0.3 * data[i] / dmax;
                if best.is_none_or(|(_, b)| pr > b) {
                    best = Some((i, pr));
                }
            }
            let Some((i, _)) = best else { break };
            done[i] = true;
            // A side is open when the lattice neighbour beyond it is still to be placed.
            let side = |dx: i32, dy: i32| {
                let q = [slots[i][0] + dx * step, slots[i][1] + dy * step];
                slots.iter().position(|&s| s == q).is_some_and(|j| !done[j])
            };
            self.open_sides = [side(-1, 0), side(1, 0), side(0, -1), side(0, 1)];
            if self.place_fill(slots[i], self.world_key(slots[i])) {
                self.patches_fill += 1;
            }
            for j in 0..slots.len() {
                if !done[j]
                    && (slots[j][0] - slots[i][0]).abs() < p
                    && (slots[j][1] - slots[i][1]).abs() < p
                {
                    conf[j] = filled_frac(self, slots[j]);
                }
            }
            progress((iter + 1) as f32 / total as f32);
        }
        Ok(())
    }

    fn place_fill(&mut self, p: [i32; 2], slot: u64) -> bool {
        let offs = desc_offsets(self.params.patch_size);
        let mut tdesc = [0.0f32; DESC];
        for (o, &[u, v]) in tdesc.iter_mut().zip(&offs) {
            *o = self.target_mid.sample(p[0] as f32 + u, p[1] as f32 + v);
        }
        let want = self.wanted_noise(p[0], p[1]);
        let relief = self.target_relief.at([p[0] as f32, p[1] as f32]);
        let raw: Vec<[f32; 3]> = self
            .fill_desc
            .par_iter()
            .enumerate()
            .map(|(i, d)| {
                let s = &self.fill_sites[i / TRANSFORMS];
                let sq: f32 = d.iter().zip(&tdesc).map(|(a, b)| (a - b) * (a - b)).sum();
                [
                    (sq / DESC as f32).sqrt(),
                    noise_cost(&s.noise, &want),
                    (s.relief - relief).abs(),
                ]
            })
            .collect();
        let norms: [f32; 3] = std::array::from_fn(|t| mean(raw.iter().map(|c| c[t])));
        let w = &self.params.weights;
        let wn = self.noise_weight();
        let cands: Vec<(usize, usize, f32)> = raw
            .par_iter()
            .enumerate()
            .map(|(i, c)| {
                let cost =
                    w.shape * c[0] / norms[0] + wn * c[1] / norms[1] + w.relief * c[2] / norms[2];
                (i / TRANSFORMS, i % TRANSFORMS, cost)
            })
            .collect();
        self.choose_and_apply(p, &cands, false, slot, false)
    }
}
