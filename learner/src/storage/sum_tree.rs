//! The sum tree behind prioritized replay: O(log n) updates of a priority and sampling in
//! proportion to priority.

/// A sum tree over `n` leaves: set a leaf, read the total, find the leaf at a prefix sum.
#[derive(Debug, Clone)]
pub struct SumTree {
    n: usize,
    tree: Vec<f64>,
}

impl SumTree {
    /// `n` leaves, all zero.
    #[must_use]
    pub fn new(n: usize) -> Self {
        let size = n.next_power_of_two();
        Self { n: size, tree: vec![0.0; 2 * size] }
    }

    /// Sets a leaf and the sums above it.
    pub fn set(&mut self, leaf: usize, value: f32) {
        let mut i = leaf + self.n;
        self.tree[i] = f64::from(value);
        while i > 1 {
            i /= 2;
            self.tree[i] = self.tree[2 * i] + self.tree[2 * i + 1];
        }
    }

    /// A leaf's value.
    #[must_use]
    pub fn get(&self, leaf: usize) -> f32 {
        self.tree[leaf + self.n] as f32
    }

    /// The sum of every leaf.
    #[must_use]
    pub fn total(&self) -> f64 {
        self.tree[1]
    }

    /// The leaf where the running sum passes `u` (0 ≤ u < total).
    #[must_use]
    pub fn find(&self, mut u: f64) -> usize {
        let mut i = 1;
        while i < self.n {
            if u < self.tree[2 * i] || self.tree[2 * i + 1] <= 0.0 {
                i *= 2;
            } else {
                u -= self.tree[2 * i];
                i = 2 * i + 1;
            }
        }
        i - self.n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_leaves_in_proportion_to_their_values() {
        let mut t = SumTree::new(5);
        for (leaf, v) in [(0, 1.0), (1, 0.0), (2, 3.0), (3, 0.5), (4, 0.5)] {
            t.set(leaf, v);
        }
        assert!((t.total() - 5.0).abs() < 1e-12);
        assert_eq!(t.get(2), 3.0);
        // Prefix sums: [0, 1) → 0, [1, 4) → 2 (leaf 1 is empty), [4, 4.5) → 3, [4.5, 5) → 4.
        for (u, leaf) in [(0.0, 0), (0.99, 0), (1.0, 2), (3.99, 2), (4.0, 3), (4.6, 4), (4.999, 4)] {
            assert_eq!(t.find(u), leaf, "u = {u}");
        }
    }
}
