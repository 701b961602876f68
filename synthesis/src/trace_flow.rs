//! D8 drainage for `trace`: flow directions on a pit-free copy of a heightmap, flow accumulation,
//! and the decomposition of the channel network into main-stem streams.
//!
//! Border cells are outlets (water leaves the grid there), so flow never runs along the border and
//! builds false rivers on it. After breaching (`pits::remove_pits`, seeded on the border) every
//! interior cell has a strictly lower 8-neighbour, so each one has a receiver and the receivers form
//! a forest rooted on the border.

use rayon::prelude::*;

use crate::pits::{N8, PitMode, remove_pits_uncounted};

/// No receiver: an outlet.
pub(crate) const NONE: u32 = u32::MAX;

/// Flow directions and accumulation of a grid.
pub(crate) struct Flow {
    /// Per cell, the 8-neighbour it drains to (steepest descent), or [`NONE`] for an outlet.
    pub receiver: Vec<u32>,
    /// Per cell, the number of cells draining through it, itself included.
    pub acc: Vec<u32>,
}

/// D8 flow of `heights` (`width * height`, row-major; cell sizes `cell` in metres). `sign` -1
/// runs the flow on the negated field (up the slopes: the divides collect the flow).
pub(crate) fn d8_flow(
    heights: &[f32],
    width: usize,
    height: usize,
    cell: [f64; 2],
    sign: f32,
) -> Flow {
    let mut z: Vec<f32> = heights.iter().map(|&h| sign * h).collect();
    remove_pits_uncounted(&mut z, width, height, None, PitMode::Breach);
    let dist: Vec<f64> = N8
        .iter()
        .map(|&(dx, dy)| (dx as f64 * cell[0]).hypot(dy as f64 * cell[1]))
        .collect();
    let mut receiver = vec![NONE; z.len()];
    receiver
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, row)| {
            if y == 0 || y + 1 == height {
                return;
            }
            for (x, r) in row.iter_mut().enumerate().take(width - 1).skip(1) {
                let i = y * width + x;
                let mut best = (0.0f64, NONE);
                for (k, &(dx, dy)) in N8.iter().enumerate() {
                    let n = (y as isize + dy) as usize * width + (x as isize + dx) as usize;
                    let drop = f64::from(z[i]) - f64::from(z[n]);
                    if drop > 0.0 && drop / dist[k] > best.0 {
                        best = (drop / dist[k], n as u32);
                    }
                }
                *r = best.1;
            }
        });
    let acc = accumulate(&receiver);
    Flow { receiver, acc }
}

/// Flow accumulation over a receiver forest, in topological order (Kahn): O(cells).
fn accumulate(receiver: &[u32]) -> Vec<u32> {
    let mut indegree = vec![0u8; receiver.len()];
    for &r in receiver {
        if r != NONE {
            indegree[r as usize] += 1;
        }
    }
    let mut acc = vec![1u32; receiver.len()];
    let mut stack: Vec<u32> = (0..receiver.len() as u32)
        .filter(|&i| indegree[i as usize] == 0)
        .collect();
    while let Some(i) = stack.pop() {
        let r = receiver[i as usize];
        if r == NONE {
            continue;
        }
        acc[r as usize] = acc[r as usize].saturating_add(acc[i as usize]);
        indegree[r as usize] -= 1;
        if indegree[r as usize] == 0 {
            stack.push(r);
        }
    }
    acc
}

/// One main-stem stream: cells from its head downstream. It ends at an outlet, or at the cell
/// where it joins a larger stream (that cell, the parent's, is included so the two touch).
pub(crate) struct Stream {
    /// Cell indices, head first.
    pub cells: Vec<u32>,
    /// Accumulation at the stream's last own cell (before the junction): its rank.
    pub outlet_acc: u32,
}

/// The channel network (cells draining at least `min_acc` cells) cut into main-stem streams: at
/// each confluence the donor with the larger accumulation continues the stream, the others end
/// there. Every channel cell belongs to exactly one stream.
pub(crate) fn streams(flow: &Flow, min_acc: u32) -> Vec<Stream> {
    let n = flow.acc.len();
    let channel = |i: usize| flow.acc[i] >= min_acc;
    // The main donor of each channel cell: its channel donor with the largest accumulation (ties
    // to the lower index, for determinism).
    let mut main_donor = vec![NONE; n];
    for i in 0..n {
        let r = flow.receiver[i];
        if r == NONE || !channel(i) {
            continue;
        }
        let m = &mut main_donor[r as usize];
        if *m == NONE || flow.acc[i] > flow.acc[*m as usize] {
            *m = i as u32;
        }
    }
    let mut out = Vec::new();
    for head in 0..n {
        if !channel(head) || main_donor[head] != NONE {
            continue;
        }
        let mut cells = vec![head as u32];
        let mut c = head;
        let mut outlet_acc = flow.acc[head];
        loop {
            let r = flow.receiver[c];
            if r == NONE {
                break;
            }
            cells.push(r);
            if main_donor[r as usize] != c as u32 {
                break;
            }
            c = r as usize;
            outlet_acc = flow.acc[c];
        }
        out.push(Stream { cells, outlet_acc });
    }
    out
}
