//! A safe, bounds-checked interface to the `gemm` crate's strided matrix multiply: the only
//! `unsafe` code of the workspace. Every view is checked to lie inside its slice, and the
//! destination view to address each element once, before `gemm` is called; views of the inputs
//! may overlap themselves (the convolution reads a padded image as overlapping rows).

#![allow(unsafe_code)]

use gemm::Parallelism;

/// A strided matrix inside a slice: element (i, j) is at `offset + i·row_stride + j·col_stride`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct View {
    pub offset: usize,
    pub rows: usize,
    pub cols: usize,
    pub row_stride: usize,
    pub col_stride: usize,
}

impl View {
    /// A dense row-major `rows × cols` matrix at `offset` with `row_stride` ≥ `cols`.
    #[must_use]
    pub fn rows(offset: usize, rows: usize, cols: usize, row_stride: usize) -> Self {
        Self { offset, rows, cols, row_stride, col_stride: 1 }
    }

    /// The transpose of this view (no data moves).
    #[must_use]
    pub fn t(self) -> Self {
        Self { offset: self.offset, rows: self.cols, cols: self.rows, row_stride: self.col_stride, col_stride: self.row_stride }
    }

    /// One past the largest index the view touches (`offset` when empty), or `None` when that
    /// index does not fit a `usize`: such a view cannot lie inside any slice. Checked arithmetic,
    /// so that release builds (which wrap on overflow) cannot be fooled by a view whose end
    /// wraps around to a small number.
    fn end(&self) -> Option<usize> {
        if self.rows == 0 || self.cols == 0 {
            Some(self.offset)
        } else {
            let last_row = (self.rows - 1).checked_mul(self.row_stride)?;
            let last_col = (self.cols - 1).checked_mul(self.col_stride)?;
            self.offset.checked_add(last_row)?.checked_add(last_col)?.checked_add(1)
        }
    }

    /// Whether distinct (i, j) address distinct elements (required of a destination). A product
    /// that overflows counts as "no": such a view is refused, never trusted.
    fn is_one_to_one(&self) -> bool {
        let (r, c) = (self.rows, self.cols);
        let rows_clear_cols = self.col_stride > 0 && c.checked_mul(self.col_stride).is_some_and(|span| self.row_stride >= span);
        let cols_clear_rows = self.row_stride > 0 && r.checked_mul(self.row_stride).is_some_and(|span| self.col_stride >= span);
        r <= 1 && (c <= 1 || self.col_stride > 0) || c <= 1 && self.row_stride > 0 || rows_clear_cols || cols_clear_rows
    }
}

/// `dst = lhs · rhs`, or `dst += lhs · rhs` when `accumulate`, on `threads` threads (1: the
/// calling thread only).
///
/// # Panics
/// If the shapes disagree, a view leaves its slice, or the destination view aliases itself: these
/// are programming errors of the caller, never data-dependent.
#[allow(clippy::too_many_arguments)]
pub fn matmul(dst: &mut [f32], d: View, accumulate: bool, lhs: &[f32], l: View, rhs: &[f32], r: View, threads: usize) {
    assert!(l.rows == d.rows && r.cols == d.cols && l.cols == r.rows, "matmul shapes: {d:?} = {l:?} · {r:?}");
    let inside = |v: View, len: usize| v.end().is_some_and(|end| end <= len);
    assert!(inside(d, dst.len()), "destination view {d:?} leaves a slice of {}", dst.len());
    assert!(inside(l, lhs.len()), "left view {l:?} leaves a slice of {}", lhs.len());
    assert!(inside(r, rhs.len()), "right view {r:?} leaves a slice of {}", rhs.len());
    assert!(d.is_one_to_one(), "destination view {d:?} addresses an element twice");
    if d.rows == 0 || d.cols == 0 {
        return;
    }
    if l.cols == 0 {
        if !accumulate {
            for i in 0..d.rows {
                for j in 0..d.cols {
                    dst[d.offset + i * d.row_stride + j * d.col_stride] = 0.0;
                }
            }
        }
        return;
    }
    let parallelism = if threads > 1 { Parallelism::Rayon(threads) } else { Parallelism::None };
    let stride = |s: usize| isize::try_from(s).expect("stride fits isize");
    // SAFETY: the asserts above keep every element gemm reads inside `lhs` and `rhs` and every
    // element it writes inside `dst`, each written element distinct; `dst` is exclusively
    // borrowed, so it cannot alias the inputs. gemm reads overlapping input views correctly.
    unsafe {
        gemm::gemm(
            d.rows,
            d.cols,
            l.cols,
            dst.as_mut_ptr().add(d.offset),
            stride(d.col_stride),
            stride(d.row_stride),
            accumulate,
            lhs.as_ptr().add(l.offset),
            stride(l.col_stride),
            stride(l.row_stride),
            rhs.as_ptr().add(r.offset),
            stride(r.col_stride),
            stride(r.row_stride),
            1.0,
            1.0,
            false,
            false,
            false,
            parallelism,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn naive(l: &[f32], lv: View, r: &[f32], rv: View) -> Vec<f32> {
        let mut out = vec![0f32; lv.rows * rv.cols];
        for i in 0..lv.rows {
            for j in 0..rv.cols {
                for k in 0..lv.cols {
                    out[i * rv.cols + j] +=
                        l[lv.offset + i * lv.row_stride + k * lv.col_stride] * r[rv.offset + k * rv.row_stride + j * rv.col_stride];
                }
            }
        }
        out
    }

    #[test]
    fn overlapping_and_transposed_views_multiply_like_the_definition() {
        let a: Vec<f32> = (0..200).map(|i| (i as f32 * 0.37).sin()).collect();
        let b: Vec<f32> = (0..300).map(|i| (i as f32 * 0.11).cos()).collect();
        // Rows of `a` overlap (stride 3, width 9), as the convolution reads them.
        let lv = View::rows(5, 40, 9, 3);
        let rv = View::rows(7, 12, 9, 20).t(); // 9 × 12, column-major
        let expected = naive(&a, lv, &b, rv);
        for threads in [1, 2] {
            let mut out = vec![1f32; 40 * 12];
            matmul(&mut out, View::rows(0, 40, 12, 12), false, &a, lv, &b, rv, threads);
            for (x, e) in out.iter().zip(&expected) {
                assert!((x - e).abs() < 1e-4, "{x} vs {e}");
            }
            matmul(&mut out, View::rows(0, 40, 12, 12), true, &a, lv, &b, rv, threads);
            for (x, e) in out.iter().zip(&expected) {
                assert!((x - 2.0 * e).abs() < 1e-4, "accumulate: {x} vs {}", 2.0 * e);
            }
        }
    }

    #[test]
    #[should_panic(expected = "leaves a slice")]
    fn a_view_past_the_end_is_refused() {
        let a = vec![0f32; 10];
        let mut out = vec![0f32; 4];
        matmul(&mut out, View::rows(0, 2, 2, 2), false, &a, View::rows(0, 2, 6, 6), &a, View::rows(0, 6, 2, 2), 1);
    }

    /// A view whose end overflows `usize`: unchecked, `offset + (rows-1)·row_stride + …` wraps
    /// (release builds) to a small number that passes the bounds check, and gemm would write far
    /// outside the slice. (Debug builds panicked on the overflow itself, with another message.)
    #[test]
    #[should_panic(expected = "destination view")]
    fn a_destination_whose_end_overflows_is_refused() {
        let a = vec![0f32; 4];
        let mut out = vec![0f32; 4];
        // end = 0 + 1·2^63 + 1·2^63 + 1 wraps to 1, which fits a slice of 4.
        let huge = 1usize << (usize::BITS - 1);
        let d = View { offset: 0, rows: 2, cols: 2, row_stride: huge, col_stride: huge };
        matmul(&mut out, d, false, &a, View::rows(0, 2, 1, 1), &a, View::rows(0, 1, 2, 2), 1);
    }

    #[test]
    fn overflowing_views_are_neither_inside_nor_one_to_one() {
        let huge = 1usize << (usize::BITS - 1);
        // rows·row_stride wraps to 0.
        let v = View { offset: 3, rows: 3, cols: 1, row_stride: huge, col_stride: 1 };
        assert_eq!(v.end(), None);
        // (0, 1) and (1, 0) are the same element; unchecked, 2·2^63 wraps to 0 and the view
        // passed as one-to-one.
        let w = View { offset: 0, rows: 2, cols: 2, row_stride: huge, col_stride: huge };
        assert!(!w.is_one_to_one());
        assert_eq!(w.end(), None);
        // Ordinary views are unaffected.
        assert_eq!(View::rows(5, 40, 9, 3).end(), Some(5 + 39 * 3 + 8 + 1));
        assert!(View::rows(0, 3, 4, 4).is_one_to_one());
        assert_eq!(View::rows(7, 0, 3, 3).end(), Some(7));
    }

    #[test]
    #[should_panic(expected = "addresses an element twice")]
    fn an_aliasing_destination_is_refused() {
        let a = vec![0f32; 16];
        let mut out = vec![0f32; 16];
        matmul(&mut out, View::rows(0, 3, 3, 1), false, &a, View::rows(0, 3, 2, 2), &a, View::rows(0, 2, 3, 3), 1);
    }
}
