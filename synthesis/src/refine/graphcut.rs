//! Minimum s-t cut by max-flow with Boykov & Kolmogorov's algorithm (2004), used to cut the seam
//! between the output so far and a new patch (Kwatra et al. 2003, as in Tasse 2011 §3.5).
//!
//! Two search trees grow from the source (S) and the sink (T) through non-saturated edges;
//! when they touch, the path is augmented, saturated tree edges make orphans, and orphans look
//! for a new parent in their tree (adoption) or become free. On grid graphs this beats
//! augmenting-path methods that rebuild their search from scratch (Dinic) by a wide margin.
//! Capacities are `f64`; a capacity of [`INFINITE`] ties a node to a terminal.

use std::collections::VecDeque;

/// Capacity that never saturates.
pub const INFINITE: f64 = 1e30;

const NONE: u32 = u32::MAX;
const TERMINAL: u32 = u32::MAX - 1;

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Tree {
    Free,
    S,
    T,
}

/// A flow network of `nodes` ordinary nodes plus a source and a sink, reached through
/// per-node terminal capacities.
#[derive(Clone, Debug)]
pub struct FlowGraph {
    /// Per edge: head node, residual capacity; edge `e ^ 1` is its reverse.
    to: Vec<u32>,
    cap: Vec<f64>,
    next: Vec<u32>,
    first: Vec<u32>,
    /// Residual terminal capacity: > 0 from the source, < 0 to the sink.
    tr: Vec<f64>,
    /// Flow already pushed straight source -> node -> sink.
    base_flow: f64,
    tree: Vec<Tree>,
    /// Edge from the node to its parent, [`TERMINAL`] for roots, [`NONE`] for none.
    parent: Vec<u32>,
}

impl FlowGraph {
    /// A graph with `nodes` ordinary nodes and no edge.
    pub fn new(nodes: usize) -> FlowGraph {
        FlowGraph {
            to: Vec::new(),
            cap: Vec::new(),
            next: Vec::new(),
            first: vec![NONE; nodes],
            tr: vec![0.0; nodes],
            base_flow: 0.0,
            tree: vec![Tree::Free; nodes],
            parent: vec![NONE; nodes],
        }
    }

    fn push(&mut self, a: usize, b: usize, c: f64) {
        self.to.push(b as u32);
        self.cap.push(c.max(0.0));
        self.next.push(self.first[a]);
        self.first[a] = (self.to.len() - 1) as u32;
    }

    /// Adds an edge `a -> b` of capacity `ab` and `b -> a` of capacity `ba` (negative = 0).
    pub fn add_edge(&mut self, a: usize, b: usize, ab: f64, ba: f64) {
        self.push(a, b, ab);
        self.push(b, a, ba);
    }

    /// Adds terminal capacities: source -> `a` of `from_source`, `a` -> sink of `to_sink`
    /// (accumulating over calls).
    pub fn add_terminals(&mut self, a: usize, from_source: f64, to_sink: f64) {
        let (s, t) = (from_source.max(0.0), to_sink.max(0.0));
        // Push what can go straight through, keep the difference.
        let cur = self.tr[a];
        let (cs, ct) = if cur > 0.0 {
            (cur + s, t)
        } else {
            (s, t - cur)
        };
        let through = cs.min(ct);
        self.base_flow += through;
        self.tr[a] = cs - ct;
    }

    /// Whether `e`'s residual capacity in the direction the tree of `a` uses is positive:
    /// S trees grow along `a -> b`, T trees along `b -> a`.
    #[inline]
    fn open(&self, tree: Tree, e: usize) -> bool {
        match tree {
            Tree::S => self.cap[e] > 0.0,
            _ => self.cap[e ^ 1] > 0.0,
        }
    }

    /// Whether `a`'s chain of parents reaches a terminal.
    fn rooted(&self, mut a: usize) -> bool {
        loop {
            match self.parent[a] {
                TERMINAL => return true,
                NONE => return false,
                e => a = self.to[e as usize] as usize,
            }
        }
    }

    /// Runs max-flow; returns the flow value (= the minimum cut's capacity).
    pub fn max_flow(&mut self) -> f64 {
        let n = self.first.len();
        let mut flow = self.base_flow;
        let mut active: VecDeque<usize> = VecDeque::new();
        let mut is_active = vec![false; n];
        for (a, act) in is_active.iter_mut().enumerate() {
            if self.tr[a] > 0.0 {
                self.tree[a] = Tree::S;
            } else if self.tr[a] < 0.0 {
                self.tree[a] = Tree::T;
            } else {
                continue;
            }
            self.parent[a] = TERMINAL;
            active.push_back(a);
            *act = true;
        }
        let mut orphans: VecDeque<usize> = VecDeque::new();
        while let Some(&a) = active.front() {
            if self.tree[a] == Tree::Free {
                active.pop_front();
                is_active[a] = false;
                continue;
            }
            let Some(ec) = self.grow(a, &mut active, &mut is_active) else {
                active.pop_front();
                is_active[a] = false;
                continue;
            };
            flow += self.augment(ec, &mut orphans);
            if flow >= INFINITE {
                return flow;
            }
            self.adopt(&mut orphans, &mut active, &mut is_active);
        }
        flow
    }

    /// Growth from active node `a`: adds its free neighbours to its tree (and to the active
    /// queue) until an edge reaches the other tree; returns that edge in the S -> T direction.
    fn grow(
        &mut self,
        a: usize,
        active: &mut VecDeque<usize>,
        is_active: &mut [bool],
    ) -> Option<usize> {
        let ta = self.tree[a];
        let mut e = self.first[a];
        while e != NONE {
            let eu = e as usize;
            if self.open(ta, eu) {
                let b = self.to[eu] as usize;
                match self.tree[b] {
                    Tree::Free => {
                        self.tree[b] = ta;
                        self.parent[b] = e ^ 1;
                        if !is_active[b] {
                            is_active[b] = true;
                            active.push_back(b);
                        }
                    }
                    tb if tb != ta => {
                        // Connecting edge in the S -> T direction.
                        return Some(if ta == Tree::S { eu } else { eu ^ 1 });
                    }
                    _ => {}
                }
            }
            e = self.next[eu];
        }
        None
    }

    /// Augmentation along S-root ... s_node -> t_node ... T-root through the connecting edge
    /// `ec`: pushes the bottleneck, queues the nodes whose parent edge saturated as orphans and
    /// returns the bottleneck.
    fn augment(&mut self, ec: usize, orphans: &mut VecDeque<usize>) -> f64 {
        let s_node = self.to[ec ^ 1] as usize;
        let t_node = self.to[ec] as usize;
        let mut bottleneck = self.cap[ec];
        let mut x = s_node;
        while self.parent[x] != TERMINAL {
            let pe = self.parent[x] as usize;
            bottleneck = bottleneck.min(self.cap[pe ^ 1]);
            x = self.to[pe] as usize;
        }
        bottleneck = bottleneck.min(self.tr[x]);
        let mut x = t_node;
        while self.parent[x] != TERMINAL {
            let pe = self.parent[x] as usize;
            bottleneck = bottleneck.min(self.cap[pe]);
            x = self.to[pe] as usize;
        }
        bottleneck = bottleneck.min(-self.tr[x]);
        self.cap[ec] -= bottleneck;
        self.cap[ec ^ 1] += bottleneck;
        let mut x = s_node;
        loop {
            let pe = self.parent[x];
            if pe == TERMINAL {
                self.tr[x] -= bottleneck;
                if self.tr[x] <= 0.0 {
                    self.tr[x] = 0.0;
                    self.parent[x] = NONE;
                    orphans.push_back(x);
                }
                break;
            }
            let pe = pe as usize;
            self.cap[pe ^ 1] -= bottleneck;
            self.cap[pe] += bottleneck;
            let next = self.to[pe] as usize;
            if self.cap[pe ^ 1] <= 0.0 {
                self.parent[x] = NONE;
                orphans.push_back(x);
            }
            x = next;
        }
        let mut x = t_node;
        loop {
            let pe = self.parent[x];
            if pe == TERMINAL {
                self.tr[x] += bottleneck;
                if self.tr[x] >= 0.0 {
                    self.tr[x] = 0.0;
                    self.parent[x] = NONE;
                    orphans.push_back(x);
                }
                break;
            }
            let pe = pe as usize;
            self.cap[pe] -= bottleneck;
            self.cap[pe ^ 1] += bottleneck;
            let next = self.to[pe] as usize;
            if self.cap[pe] <= 0.0 {
                self.parent[x] = NONE;
                orphans.push_back(x);
            }
            x = next;
        }
        bottleneck
    }

    /// Adoption: each orphan takes a rooted neighbour of its tree as new parent, or becomes
    /// free, re-activating its tree neighbours and orphaning its children.
    fn adopt(
        &mut self,
        orphans: &mut VecDeque<usize>,
        active: &mut VecDeque<usize>,
        is_active: &mut [bool],
    ) {
        while let Some(o) = orphans.pop_front() {
            let to = self.tree[o];
            let mut e = self.first[o];
            let mut found = None;
            while e != NONE {
                let eu = e as usize;
                let b = self.to[eu] as usize;
                // Residual from the parent side: S needs b -> o, T needs o -> b.
                let ok = match to {
                    Tree::S => self.cap[eu ^ 1] > 0.0,
                    _ => self.cap[eu] > 0.0,
                };
                if ok && self.tree[b] == to && self.rooted(b) {
                    found = Some(e);
                    break;
                }
                e = self.next[eu];
            }
            if let Some(e) = found {
                self.parent[o] = e;
                continue;
            }
            let mut e = self.first[o];
            while e != NONE {
                let eu = e as usize;
                let b = self.to[eu] as usize;
                if self.tree[b] == to {
                    let ok = match to {
                        Tree::S => self.cap[eu ^ 1] > 0.0,
                        _ => self.cap[eu] > 0.0,
                    };
                    if ok && !is_active[b] {
                        is_active[b] = true;
                        active.push_back(b);
                    }
                    if self.parent[b] == e ^ 1 {
                        self.parent[b] = NONE;
                        orphans.push_back(b);
                    }
                }
                e = self.next[eu];
            }
            self.tree[o] = Tree::Free;
        }
    }

    /// After [`FlowGraph::max_flow`]: per node, whether it is on the source side of the minimum
    /// cut (in the source's search tree, i.e. reachable from the source in the residual graph).
    pub fn source_side(&self) -> Vec<bool> {
        self.tree.iter().map(|&t| t == Tree::S).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classic_network() {
        // CLRS figure 26.1 with s and t folded into terminal capacities: max flow 23.
        let mut g = FlowGraph::new(4);
        g.add_terminals(0, 16.0, 0.0);
        g.add_terminals(1, 13.0, 0.0);
        g.add_edge(0, 2, 12.0, 0.0);
        g.add_edge(1, 0, 4.0, 0.0);
        g.add_edge(2, 1, 9.0, 0.0);
        g.add_edge(1, 3, 14.0, 0.0);
        g.add_edge(3, 2, 7.0, 0.0);
        g.add_terminals(2, 0.0, 20.0);
        g.add_terminals(3, 0.0, 4.0);
        assert!((g.max_flow() - 23.0).abs() < 1e-9);
        // The minimum cut {s, 0, 1, 3} | {2, t}: capacity 12 + 7 + 4 = 23.
        assert_eq!(g.source_side(), vec![true, true, false, true]);
    }
}
