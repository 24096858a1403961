//! Spatial sorting of the particle storage (LAMMPS/LIGGGHTS `atom_modify sort`).
//!
//! Particles are stored in case order, which a pour or a flow scrambles: neighbours in
//! space end up far apart in memory, and above a few thousand grains every pair of the
//! pair pass and every reverse slot of the gather is a cache miss. Renumbering the free
//! spheres along a Morton (Z-order) curve over the neighbour-list cells at a rebuild puts
//! a particle's neighbours a few slots away, so the passes stream through memory.
//!
//! A renumbering changes no physics but the order of floating-point sums (a particle's
//! own pairs and reverse slots become other pairs), so a sorted run differs from an
//! unsorted one by rounding, and then by the chaos of a dense packing. Results remain
//! bit-identical for any thread count: the order depends only on positions. Outputs
//! that name particles go through the index map ([`super::Simulation::case_order`]), so
//! they keep case (id) order.

use super::neighbor::Grid;
use crate::numerics::vec3::V3;

/// Fewest free spheres for which the engine sorts by default. Below this the state a
/// step touches (about 250 bytes per sphere: positions, velocities, spins, forces,
/// torques, radii, masses, kick factors, wall history, a few pairs of history) fits in
/// the 1 MiB L2 of one core, so reordering cannot save a cache miss; and every micro
/// case (at most a few hundred grains) then runs exactly as before, bit for bit.
pub const DEFAULT_MIN_PARTICLES: usize = 4096;

/// Steps between two sorts by default, LAMMPS' default `atom_modify sort 1000`: a sort
/// happens at the first neighbour-list build at least this many steps after the last.
pub const DEFAULT_EVERY: u64 = 1000;

/// Spreads the low 21 bits of `v` to every third bit.
fn spread3(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// Morton key of a cell: bits of x, y and z interleaved.
pub(crate) fn morton(c: [usize; 3]) -> u64 {
    spread3(c[0] as u64) | spread3(c[1] as u64) << 1 | spread3(c[2] as u64) << 2
}

/// The new order of the first `n_sorted` particles (the rest keep their places): new
/// particle k is old particle `old_of_new[k]`, sorted by the Morton key of its cell of
/// edge `cutoff` (the neighbour-list grid), ties in the old order so the result depends
/// on positions only. `None` when the order would not change.
pub(crate) fn morton_order(
    x: &[V3],
    n_sorted: usize,
    cutoff: f64,
    lo: V3,
    hi: V3,
) -> Option<Vec<u32>> {
    let grid = Grid::new(lo, hi, cutoff);
    let mut keyed: Vec<(u64, u32)> = x[..n_sorted]
        .iter()
        .enumerate()
        .map(|(k, p)| (morton(grid.coord(*p)), k as u32))
        .collect();
    if keyed.windows(2).all(|w| w[0].0 <= w[1].0) {
        return None;
    }
    keyed.sort_unstable();
    let mut order: Vec<u32> = keyed.into_iter().map(|(_, k)| k).collect();
    order.extend(n_sorted as u32..x.len() as u32);
    Some(order)
}

/// `v[k] = old v[old_of_new[k]]`.
pub fn gather<T: Copy>(v: &mut Vec<T>, old_of_new: &[u32]) {
    if v.is_empty() {
        return;
    }
    debug_assert_eq!(v.len(), old_of_new.len());
    *v = old_of_new.iter().map(|&k| v[k as usize]).collect();
}

/// [`gather`] of `stride` consecutive entries per particle.
pub(crate) fn gather_strided<T: Copy>(v: &mut Vec<T>, old_of_new: &[u32], stride: usize) {
    if v.is_empty() {
        return;
    }
    debug_assert_eq!(v.len(), old_of_new.len() * stride);
    let mut out = Vec::with_capacity(v.len());
    for &k in old_of_new {
        let k = k as usize;
        out.extend_from_slice(&v[k * stride..(k + 1) * stride]);
    }
    *v = out;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_interleaves_bits() {
        assert_eq!(morton([1, 0, 0]), 1);
        assert_eq!(morton([0, 1, 0]), 2);
        assert_eq!(morton([0, 0, 1]), 4);
        assert_eq!(morton([3, 3, 3]), 63);
        assert_eq!(morton([(1 << 21) - 1, 0, 0]), 0x1249_2492_4924_9249);
    }

    #[test]
    fn order_is_a_permutation_that_keeps_the_tail() {
        let x: Vec<V3> = (0..50)
            .map(|k| {
                let t = (k * 37 % 50) as f64;
                [t * 1e-3, (t * 7.0 % 50.0) * 1e-3, (t * 13.0 % 50.0) * 1e-3]
            })
            .collect();
        let order = morton_order(&x, 40, 5e-3, [0.0; 3], [0.05; 3]).expect("scrambled input");
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..50).collect::<Vec<u32>>());
        assert_eq!(&order[40..], &(40..50).collect::<Vec<u32>>()[..]);
        let mut sorted = x.clone();
        gather(&mut sorted, &order);
        assert!(morton_order(&sorted, 40, 5e-3, [0.0; 3], [0.05; 3]).is_none());
        let mut pairs: Vec<u32> = (0..100).collect();
        gather_strided(&mut pairs, &order, 2);
        assert_eq!(pairs[0..2], [2 * order[0], 2 * order[0] + 1]);
    }
}
