//! A growable buffer whose first element starts a cache line (64 bytes), for the operands of the
//! bf16 kernels. An AMX tile row or a zmm register is 64 bytes: read or written at an address
//! that is not a multiple of 64, each one touches two cache lines, which halves what L1 delivers
//! per tile load and store. `Vec`'s allocations are aligned only to their element type (and
//! glibc's large ones sit 16 bytes past a page), so this one keeps a few elements of slack in
//! front and starts the slice at the first aligned one. Safe code only: the address is read,
//! never forged.

use std::ops::{Deref, DerefMut};

/// Bytes of a cache line, a tile row and a zmm register.
pub const LINE: usize = 64;

/// A `Vec<T>` seen from its first element aligned to [`LINE`] bytes.
#[derive(Default)]
pub struct Aligned<T> {
    /// The storage: `start` elements of slack, then the values.
    buf: Vec<T>,
    start: usize,
}

impl<T: Copy + Default> Aligned<T> {
    /// `len` default values (zeros).
    #[must_use]
    pub fn zeroed(len: usize) -> Self {
        // `vec!` of zeros asks the allocator for zeroed memory (calloc: fresh pages need no
        // writing), where `resize` would write every value.
        let buf = vec![T::default(); len + slack::<T>()];
        let start = line_offset(&buf);
        let mut a = Self { buf, start };
        a.buf.truncate(start + len);
        a
    }

    /// The values of `src`, aligned.
    #[must_use]
    pub fn from_slice(src: &[T]) -> Self {
        let mut a = Self::zeroed(0);
        a.reserve(src.len());
        a.buf.extend_from_slice(src);
        a
    }

    /// Resizes to `len` values as `Vec::resize` does (kept values stay, new ones are `value`).
    pub fn resize(&mut self, len: usize, value: T) {
        self.reserve(len);
        self.buf.resize(self.start + len, value);
    }

    /// Drops every value (the storage stays).
    pub fn clear(&mut self) {
        self.buf.truncate(self.start);
    }

    /// Makes room for `len` values without moving the storage again, keeping the values.
    fn reserve(&mut self, len: usize) {
        if self.buf.capacity() >= self.start + len && self.buf.capacity() > 0 {
            return;
        }
        let mut buf: Vec<T> = Vec::with_capacity(len + slack::<T>());
        let start = line_offset(&buf);
        buf.resize(start, T::default());
        buf.extend_from_slice(&self.buf[self.start..]);
        self.buf = buf;
        self.start = start;
        debug_assert_eq!(self.buf[self.start..].as_ptr().addr() % LINE, 0);
    }
}

/// Elements of slack that leave room to start a line anywhere in an allocation.
fn slack<T>() -> usize {
    const { assert!(size_of::<T>() > 0 && LINE.is_multiple_of(size_of::<T>()), "Aligned: elements must tile a cache line") };
    LINE / size_of::<T>()
}

/// Elements from the start of `buf`'s allocation to the next line: T's alignment divides
/// [`LINE`] for the types used here (u16, f32), so the count is whole.
fn line_offset<T>(buf: &[T]) -> usize {
    (LINE - buf.as_ptr().addr() % LINE) % LINE / size_of::<T>()
}

impl<T> Deref for Aligned<T> {
    type Target = [T];

    fn deref(&self) -> &[T] {
        &self.buf[self.start..]
    }
}

impl<T> DerefMut for Aligned<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        &mut self.buf[self.start..]
    }
}

impl<T: Copy + Default> Clone for Aligned<T> {
    fn clone(&self) -> Self {
        Self::from_slice(self)
    }
}

impl<T: PartialEq> PartialEq for Aligned<T> {
    fn eq(&self, other: &Self) -> bool {
        self[..] == other[..]
    }
}

impl<T: std::fmt::Debug> std::fmt::Debug for Aligned<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn is_aligned<T>(s: &[T]) -> bool {
        s.as_ptr().addr().is_multiple_of(LINE)
    }

    #[test]
    fn starts_on_a_line_and_keeps_values_across_growth() {
        let mut a: Aligned<u16> = Aligned::zeroed(3);
        assert!(is_aligned(&a));
        a.copy_from_slice(&[1, 2, 3]);
        a.resize(100_000, 7);
        assert!(is_aligned(&a));
        assert_eq!(&a[..4], &[1, 2, 3, 7]);
        assert_eq!(a.len(), 100_000);
        a.resize(2, 0);
        assert_eq!(&a[..], &[1, 2]);
        a.clear();
        assert!(a.is_empty());
        a.resize(5, 9);
        assert!(is_aligned(&a));
        assert_eq!(&a[..], &[9; 5]);
        // Many allocations of odd sizes: each starts a line (malloc alone gives 16 bytes).
        for n in 1..200 {
            let b: Aligned<f32> = Aligned::zeroed(n * 37);
            assert!(is_aligned(&b), "{n}");
            let c = b.clone();
            assert!(is_aligned(&c) && c == b);
        }
        assert!(is_aligned(&Aligned::<u16>::from_slice(&[1, 2, 3])));
    }
}
