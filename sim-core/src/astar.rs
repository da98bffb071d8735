//! A* search over any graph given by a successor function, with a consistent heuristic.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// The cheapest path found by [`astar`]: total cost and the nodes from a start to a goal.
#[derive(Debug, Clone, PartialEq)]
pub struct Path {
    pub cost: f32,
    pub nodes: Vec<usize>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Entry {
    f: f32,
    g: f32,
    node: usize,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        // Min-heap on f, ties broken by larger g (deeper first), then node index: fully
        // deterministic order.
        other.f.total_cmp(&self.f).then(self.g.total_cmp(&other.g)).then(other.node.cmp(&self.node))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Finds the cheapest path over nodes `0..n` from any of `starts` (node, initial cost) to a node
/// for which `finish` returns the cost of completing there (`None` elsewhere).
///
/// `successors(u, out)` pushes `(v, edge_cost)` with non-negative costs. `heuristic(u)` must never
/// exceed the true remaining cost from `u` (admissible) and must satisfy
/// `h(u) <= cost(u,v) + h(v)` and `h(u) <= finish(u)` (consistent); then the result is optimal.
pub fn astar(
    n: usize,
    starts: &[(usize, f32)],
    finish: impl Fn(usize) -> Option<f32>,
    mut successors: impl FnMut(usize, &mut Vec<(usize, f32)>),
    heuristic: impl Fn(usize) -> f32,
) -> Option<Path> {
    // Node `n` is a virtual goal reached from every finishing node.
    let goal = n;
    let mut g = vec![f32::INFINITY; n + 1];
    let mut parent = vec![usize::MAX; n + 1];
    let mut closed = vec![false; n + 1];
    let mut open = BinaryHeap::new();
    for &(s, c) in starts {
        if s < n && c < g[s] {
            g[s] = c;
            open.push(Entry { f: c + heuristic(s), g: c, node: s });
        }
    }
    let mut buf = Vec::new();
    while let Some(Entry { g: gu, node: u, .. }) = open.pop() {
        if closed[u] || gu > g[u] {
            continue;
        }
        closed[u] = true;
        if u == goal {
            let mut nodes = Vec::new();
            let mut v = parent[goal];
            while v != usize::MAX {
                nodes.push(v);
                v = parent[v];
            }
            nodes.reverse();
            return Some(Path { cost: gu, nodes });
        }
        if let Some(c) = finish(u) {
            let gv = gu + c;
            if gv < g[goal] {
                g[goal] = gv;
                parent[goal] = u;
                open.push(Entry { f: gv, g: gv, node: goal });
            }
        }
        buf.clear();
        successors(u, &mut buf);
        for &(v, c) in &buf {
            let gv = gu + c;
            if !closed[v] && gv < g[v] {
                g[v] = gv;
                parent[v] = u;
                open.push(Entry { f: gv + heuristic(v), g: gv, node: v });
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Brute force: Bellman–Ford relaxation until nothing changes.
    fn brute_force(n: usize, edges: &[(usize, usize, f32)], start: usize, goal: usize) -> Option<f32> {
        let mut d = vec![f32::INFINITY; n];
        d[start] = 0.0;
        for _ in 0..n {
            for &(u, v, c) in edges {
                if d[u] + c < d[v] {
                    d[v] = d[u] + c;
                }
            }
        }
        d[goal].is_finite().then_some(d[goal])
    }

    #[test]
    fn matches_brute_force_on_random_geometric_graphs() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for case in 0..200 {
            let n = 2 + (rng.next_u32() % 40) as usize;
            let pts: Vec<(f32, f32)> = (0..n)
                .map(|_| (rng.next_u32() as f32 / u32::MAX as f32 * 100.0, rng.next_u32() as f32 / u32::MAX as f32 * 100.0))
                .collect();
            let dist = |a: usize, b: usize| ((pts[a].0 - pts[b].0).powi(2) + (pts[a].1 - pts[b].1).powi(2)).sqrt();
            let mut edges = Vec::new();
            let m = n * (1 + (rng.next_u32() % 3) as usize);
            for _ in 0..m {
                let (u, v) = ((rng.next_u32() as usize) % n, (rng.next_u32() as usize) % n);
                // Edge cost at least the straight-line distance, as for roads.
                let detour = 1.0 + (rng.next_u32() % 100) as f32 / 50.0;
                edges.push((u, v, dist(u, v) * detour));
            }
            let (start, goal) = (0, n - 1);
            let found = astar(
                n,
                &[(start, 0.0)],
                |u| (u == goal).then_some(0.0),
                |u, out| out.extend(edges.iter().filter(|e| e.0 == u).map(|e| (e.1, e.2))),
                |u| dist(u, goal),
            );
            let expected = brute_force(n, &edges, start, goal);
            match (found, expected) {
                (Some(p), Some(e)) => {
                    assert!((p.cost - e).abs() <= 1e-3 * e.max(1.0), "case {case}: A* {} vs brute force {e}", p.cost);
                    assert_eq!((p.nodes[0], *p.nodes.last().unwrap()), (start, goal));
                    let along: f32 = p
                        .nodes
                        .windows(2)
                        .map(|w| edges.iter().filter(|e| e.0 == w[0] && e.1 == w[1]).map(|e| e.2).fold(f32::INFINITY, f32::min))
                        .sum();
                    assert!((along - p.cost).abs() <= 1e-3 * along.max(1.0), "case {case}: path cost {along} vs reported {}", p.cost);
                }
                (None, None) => {}
                (f, e) => panic!("case {case}: A* {f:?} vs brute force {e:?}"),
            }
        }
    }

    #[test]
    fn finish_costs_and_multiple_starts() {
        // 0 -> 1 -> 2, finishing at 1 costs 10, at 2 costs 0.
        let edges = [(0usize, 1usize, 1.0f32), (1, 2, 1.0)];
        let p = astar(
            3,
            &[(0, 0.0), (1, 5.0)],
            |u| match u {
                1 => Some(10.0),
                2 => Some(0.0),
                _ => None,
            },
            |u, out| out.extend(edges.iter().filter(|e| e.0 == u).map(|e| (e.1, e.2))),
            |_| 0.0,
        )
        .unwrap();
        assert_eq!(p, Path { cost: 2.0, nodes: vec![0, 1, 2] });
    }
}
