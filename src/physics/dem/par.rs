//! Deterministic data-parallel loops over blocks of particles.
//!
//! Every pass of a step works particle by particle: a particle's result depends only on
//! the state before the pass, never on which thread computed it or on the order blocks
//! finish, so results are bit-identical for any thread count. Blocks write disjoint
//! ranges of the per-particle and per-pair arrays (and the pair pass writes each reverse
//! slot exactly once), which [`Shared`] lets several threads do through raw pointers.

use rayon::prelude::*;
use std::ops::Range;

/// Particles per block: large enough that scheduling costs nothing, small enough that two
/// threads balance well on 10^4 particles.
pub(crate) const BLOCK: usize = 512;

/// A mutable slice shared by the blocks of one pass.
#[derive(Clone, Copy)]
pub(crate) struct Shared<T>(*mut T, usize);

// SAFETY: a `Shared` is only dereferenced through `slice`/`write`, whose callers
// guarantee that concurrent accesses touch disjoint elements.
unsafe impl<T: Send> Send for Shared<T> {}
unsafe impl<T: Send> Sync for Shared<T> {}

impl<T> Shared<T> {
    pub fn new(s: &mut [T]) -> Self {
        Shared(s.as_mut_ptr(), s.len())
    }

    /// # Safety
    /// `r` lies within the slice and no other live reference (in any thread) overlaps it.
    #[inline(always)]
    pub unsafe fn slice<'a>(self, r: Range<usize>) -> &'a mut [T] {
        debug_assert!(r.start <= r.end && r.end <= self.1);
        unsafe { std::slice::from_raw_parts_mut(self.0.add(r.start), r.end - r.start) }
    }

    /// # Safety
    /// `k` is in bounds and no other thread accesses element `k` during the pass.
    #[inline(always)]
    pub unsafe fn write(self, k: usize, v: T) {
        debug_assert!(k < self.1);
        unsafe { self.0.add(k).write(v) }
    }
}

/// Runs `f` on every block `b * BLOCK .. min((b + 1) * BLOCK, n)` of `0..n`, in parallel.
pub(crate) fn for_blocks(n: usize, f: impl Fn(Range<usize>) + Sync + Send) {
    let nb = n.div_ceil(BLOCK);
    (0..nb)
        .into_par_iter()
        .for_each(|b| f(b * BLOCK..((b + 1) * BLOCK).min(n)));
}

/// [`for_blocks`] with a per-block result combined by `reduce`, which must be associative
/// and commutative (min, or) so the result does not depend on the split.
pub(crate) fn map_reduce_blocks<R: Send + Sync + Copy>(
    n: usize,
    identity: R,
    map: impl Fn(Range<usize>) -> R + Sync + Send,
    reduce: impl Fn(R, R) -> R + Sync + Send,
) -> R {
    let nb = n.div_ceil(BLOCK);
    (0..nb)
        .into_par_iter()
        .map(|b| map(b * BLOCK..((b + 1) * BLOCK).min(n)))
        .reduce(|| identity, reduce)
}
