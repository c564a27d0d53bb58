//! [`Small`]: a short array of `Copy` values stored inline up to `N` elements (no heap
//! allocation), spilling to a `Vec` beyond. Used for per-band weights and per-material scratch
//! in the photon tracker so that a scattering event allocates nothing for the usual band and
//! material counts (LiDAR: one band).

use std::ops::{Deref, DerefMut};

/// Up to `N` values inline, more on the heap; derefs to a slice.
#[derive(Debug, Clone)]
pub enum Small<T: Copy + Default, const N: usize> {
    /// `len ≤ N` values in `buf[..len]`.
    Inline {
        /// Number of values.
        len: usize,
        /// Storage.
        buf: [T; N],
    },
    /// More than `N` values.
    Heap(Vec<T>),
}

impl<T: Copy + Default, const N: usize> Small<T, N> {
    /// `n` copies of `v`.
    #[inline]
    pub fn from_elem(v: T, n: usize) -> Self {
        if n <= N {
            Small::Inline {
                len: n,
                buf: [v; N],
            }
        } else {
            Small::Heap(vec![v; n])
        }
    }

    /// A copy of `s`.
    #[inline]
    pub fn from_slice(s: &[T]) -> Self {
        if s.len() <= N {
            let mut buf = [T::default(); N];
            buf[..s.len()].copy_from_slice(s);
            Small::Inline { len: s.len(), buf }
        } else {
            Small::Heap(s.to_vec())
        }
    }

    /// `f(i)` for `i` in `0..n`.
    #[inline]
    pub fn from_fn(n: usize, mut f: impl FnMut(usize) -> T) -> Self {
        let mut s = Self::from_elem(T::default(), n);
        for (i, x) in s.iter_mut().enumerate() {
            *x = f(i);
        }
        s
    }
}

impl<T: Copy + Default, const N: usize> Deref for Small<T, N> {
    type Target = [T];
    #[inline]
    fn deref(&self) -> &[T] {
        match self {
            Small::Inline { len, buf } => &buf[..*len],
            Small::Heap(v) => v,
        }
    }
}

impl<T: Copy + Default, const N: usize> DerefMut for Small<T, N> {
    #[inline]
    fn deref_mut(&mut self) -> &mut [T] {
        match self {
            Small::Inline { len, buf } => &mut buf[..*len],
            Small::Heap(v) => v,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inline_and_spilled_behave_like_slices() {
        let a: Small<f64, 4> = Small::from_elem(1.5, 3);
        assert!(matches!(a, Small::Inline { .. }));
        assert_eq!(&a[..], &[1.5, 1.5, 1.5]);
        let mut b: Small<f64, 2> = Small::from_slice(&[1.0, 2.0, 3.0]);
        assert!(matches!(b, Small::Heap(_)));
        b[2] = 4.0;
        assert_eq!(&b[..], &[1.0, 2.0, 4.0]);
        let c: Small<u32, 4> = Small::from_fn(4, |i| i as u32 * 2);
        assert_eq!(&c[..], &[0, 2, 4, 6]);
        let e: Small<f64, 4> = Small::from_slice(&[]);
        assert!(e.is_empty());
    }
}
