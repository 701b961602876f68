//! Minimum s-t cut by max-flow (Dinic: BFS level graph, blocking flows by DFS), used to cut the
//! seam between the output so far and a new patch (Kwatra et al. 2003, as in Tasse 2011 §3.5).
//!
//! The graphs are small (the overlap of one patch: a few thousand nodes), so Dinic's simplicity
//! wins over Boykov-Kolmogorov's tree reuse. Capacities are `f64`; a capacity of
//! [`INFINITE`] ties a node to a terminal.

/// Capacity that never saturates.
pub const INFINITE: f64 = 1e30;

/// A flow network with a source and a sink besides `nodes` ordinary nodes.
#[derive(Clone, Debug)]
pub struct FlowGraph {
    nodes: usize,
    /// Per edge: head node, residual capacity; edge `e ^ 1` is its reverse.
    to: Vec<u32>,
    cap: Vec<f64>,
    next: Vec<u32>,
    first: Vec<u32>,
    level: Vec<i32>,
    cursor: Vec<u32>,
}

const NONE: u32 = u32::MAX;

impl FlowGraph {
    /// A graph with `nodes` ordinary nodes (`0..nodes`) and no edge.
    pub fn new(nodes: usize) -> FlowGraph {
        FlowGraph {
            nodes,
            to: Vec::new(),
            cap: Vec::new(),
            next: Vec::new(),
            first: vec![NONE; nodes + 2],
            level: Vec::new(),
            cursor: Vec::new(),
        }
    }

    /// The source's index.
    pub fn source(&self) -> usize {
        self.nodes
    }

    /// The sink's index.
    pub fn sink(&self) -> usize {
        self.nodes + 1
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

    /// Adds terminal links: source -> `a` of capacity `from_source`, `a` -> sink of `to_sink`.
    pub fn add_terminals(&mut self, a: usize, from_source: f64, to_sink: f64) {
        let (s, t) = (self.source(), self.sink());
        if from_source > 0.0 {
            self.add_edge(s, a, from_source, 0.0);
        }
        if to_sink > 0.0 {
            self.add_edge(a, t, to_sink, 0.0);
        }
    }

    fn bfs(&mut self) -> bool {
        let total = self.nodes + 2;
        self.level.clear();
        self.level.resize(total, -1);
        let mut queue = std::collections::VecDeque::new();
        let s = self.source();
        self.level[s] = 0;
        queue.push_back(s);
        while let Some(a) = queue.pop_front() {
            let mut e = self.first[a];
            while e != NONE {
                let b = self.to[e as usize] as usize;
                if self.cap[e as usize] > 0.0 && self.level[b] < 0 {
                    self.level[b] = self.level[a] + 1;
                    queue.push_back(b);
                }
                e = self.next[e as usize];
            }
        }
        self.level[self.sink()] >= 0
    }

    /// Blocking-flow search from `a` with at most `limit` units (iterative, explicit stack).
    fn dfs(&mut self, limit: f64) -> f64 {
        let (s, t) = (self.source(), self.sink());
        // Stack of edges taken from the source.
        let mut path: Vec<u32> = Vec::new();
        let mut a = s;
        loop {
            if a == t {
                let mut push = limit;
                for &e in &path {
                    push = push.min(self.cap[e as usize]);
                }
                for &e in &path {
                    self.cap[e as usize] -= push;
                    self.cap[(e ^ 1) as usize] += push;
                }
                return push;
            }
            let mut advanced = false;
            while self.cursor[a] != NONE {
                let e = self.cursor[a] as usize;
                let b = self.to[e] as usize;
                if self.cap[e] > 0.0 && self.level[b] == self.level[a] + 1 {
                    path.push(e as u32);
                    a = b;
                    advanced = true;
                    break;
                }
                self.cursor[a] = self.next[e];
            }
            if !advanced {
                // Dead end: retreat, and skip the edge that led here.
                self.level[a] = -1;
                match path.pop() {
                    None => return 0.0,
                    Some(e) => {
                        a = self.to[(e ^ 1) as usize] as usize;
                        self.cursor[a] = self.next[self.cursor[a] as usize];
                    }
                }
            }
        }
    }

    /// Runs max-flow; returns the flow value (= the minimum cut's capacity).
    pub fn max_flow(&mut self) -> f64 {
        let mut flow = 0.0;
        while self.bfs() {
            self.cursor = self.first.clone();
            loop {
                let f = self.dfs(INFINITE);
                if f <= 0.0 {
                    break;
                }
                flow += f;
                if flow >= INFINITE {
                    return flow;
                }
            }
        }
        flow
    }

    /// After [`FlowGraph::max_flow`]: whether `a` is on the source side of the minimum cut
    /// (reachable from the source in the residual graph).
    pub fn source_side(&mut self) -> Vec<bool> {
        self.bfs();
        (0..self.nodes).map(|a| self.level[a] >= 0).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classic_network() {
        // CLRS figure 26.1: max flow 23.
        let mut g = FlowGraph::new(4);
        let (s, t) = (g.source(), g.sink());
        g.add_edge(s, 0, 16.0, 0.0);
        g.add_edge(s, 1, 13.0, 0.0);
        g.add_edge(0, 2, 12.0, 0.0);
        g.add_edge(1, 0, 4.0, 0.0);
        g.add_edge(2, 1, 9.0, 0.0);
        g.add_edge(1, 3, 14.0, 0.0);
        g.add_edge(3, 2, 7.0, 0.0);
        g.add_edge(2, t, 20.0, 0.0);
        g.add_edge(3, t, 4.0, 0.0);
        assert!((g.max_flow() - 23.0).abs() < 1e-9);
    }
}
