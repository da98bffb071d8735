//! A safe, bounds-checked interface to the `gemm` crate's strided matrix multiply: the only
//! `unsafe` code of the workspace. Every view is checked to lie inside its slice, and the
//! destination view to address each element once, before `gemm` is called (by [`Product::new`],
//! which returns why not); views of the inputs may overlap themselves (the convolution reads a
//! padded image as overlapping rows).

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

/// Why [`Product::new`] refused a product's views: a programming error of the caller, never
/// data-dependent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ViewError {
    #[error("matmul shapes: {d:?} = {l:?} · {r:?}")]
    Shapes { d: View, l: View, r: View },
    #[error("{operand} view {view:?} leaves a slice of {len}")]
    Outside { operand: &'static str, view: View, len: usize },
    #[error("destination view {0:?} addresses an element twice")]
    Aliases(View),
}

/// `dst = lhs · rhs` with views checked once, by the checked constructor, against the lengths of
/// their slices; [`Product::run`] then needs only slices that long.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Product {
    d: View,
    l: View,
    r: View,
    /// The lengths of the destination, left and right slices the views were checked against.
    lens: [usize; 3],
}

impl Product {
    /// The product of views `l` of a slice of `lhs_len` and `r` of one of `rhs_len` into view `d`
    /// of one of `dst_len`.
    ///
    /// # Errors
    /// If the shapes disagree, a view leaves its slice, or the destination view aliases itself.
    pub fn new(dst_len: usize, d: View, lhs_len: usize, l: View, rhs_len: usize, r: View) -> Result<Self, ViewError> {
        if !(l.rows == d.rows && r.cols == d.cols && l.cols == r.rows) {
            return Err(ViewError::Shapes { d, l, r });
        }
        for (operand, view, len) in [("destination", d, dst_len), ("left", l, lhs_len), ("right", r, rhs_len)] {
            if view.end().is_none_or(|end| end > len) {
                return Err(ViewError::Outside { operand, view, len });
            }
        }
        if !d.is_one_to_one() {
            return Err(ViewError::Aliases(d));
        }
        Ok(Self { d, l, r, lens: [dst_len, lhs_len, rhs_len] })
    }

    /// `dst = lhs · rhs`, or `dst += lhs · rhs` when `accumulate`, on `threads` threads (1: the
    /// calling thread only).
    ///
    /// # Panics
    /// If a slice is shorter than the constructor was told.
    pub fn run(&self, dst: &mut [f32], accumulate: bool, lhs: &[f32], rhs: &[f32], threads: usize) {
        let Self { d, l, r, lens } = *self;
        assert!(
            dst.len() >= lens[0] && lhs.len() >= lens[1] && rhs.len() >= lens[2],
            "gemm::Product::run: slices of {}, {} and {} for one checked against {lens:?}",
            dst.len(),
            lhs.len(),
            rhs.len()
        );
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
        // SAFETY: the checks of `new` and the assert above keep every element gemm reads inside
        // `lhs` and `rhs` and every element it writes inside `dst`, each written element distinct;
        // `dst` is exclusively borrowed, so it cannot alias the inputs. gemm reads overlapping
        // input views correctly.
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
}

/// `dst = lhs · rhs`, or `dst += lhs · rhs` when `accumulate`, on `threads` threads (1: the
/// calling thread only): a [`Product`] made and run at once.
///
/// # Panics
/// If the shapes disagree, a view leaves its slice, or the destination view aliases itself (the
/// [`ViewError`]s of [`Product::new`]): programming errors of the caller, never data-dependent.
#[allow(clippy::too_many_arguments)]
pub fn matmul(dst: &mut [f32], d: View, accumulate: bool, lhs: &[f32], l: View, rhs: &[f32], r: View, threads: usize) {
    match Product::new(dst.len(), d, lhs.len(), l, rhs.len(), r) {
        Ok(product) => product.run(dst, accumulate, lhs, rhs, threads),
        Err(e) => panic!("gemm::matmul: {e}"),
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
    fn a_view_past_the_end_is_refused() {
        let l = View::rows(0, 2, 6, 6);
        let refused = Product::new(4, View::rows(0, 2, 2, 2), 10, l, 10, View::rows(0, 6, 2, 2));
        assert_eq!(refused, Err(ViewError::Outside { operand: "left", view: l, len: 10 }));
        assert_eq!(refused.unwrap_err().to_string(), format!("left view {l:?} leaves a slice of 10"));
        // Shapes that disagree are refused first.
        let r = View::rows(0, 5, 2, 2);
        assert!(matches!(Product::new(4, View::rows(0, 2, 2, 2), 100, l, 100, r), Err(ViewError::Shapes { .. })));
    }

    /// A view whose end overflows `usize`: unchecked, `offset + (rows-1)·row_stride + …` wraps
    /// (release builds) to a small number that passes the bounds check, and gemm would write far
    /// outside the slice. (Debug builds panicked on the overflow itself, with another message.)
    #[test]
    fn a_destination_whose_end_overflows_is_refused() {
        // end = 0 + 1·2^63 + 1·2^63 + 1 wraps to 1, which fits a slice of 4.
        let huge = 1usize << (usize::BITS - 1);
        let d = View { offset: 0, rows: 2, cols: 2, row_stride: huge, col_stride: huge };
        let refused = Product::new(4, d, 4, View::rows(0, 2, 1, 1), 4, View::rows(0, 1, 2, 2));
        assert_eq!(refused, Err(ViewError::Outside { operand: "destination", view: d, len: 4 }));
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
    fn an_aliasing_destination_is_refused() {
        let d = View::rows(0, 3, 3, 1);
        let refused = Product::new(16, d, 16, View::rows(0, 3, 2, 2), 16, View::rows(0, 2, 3, 3));
        assert_eq!(refused, Err(ViewError::Aliases(d)));
        assert!(refused.unwrap_err().to_string().contains("addresses an element twice"));
    }
}
