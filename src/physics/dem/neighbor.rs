//! Linked cells + Verlet skin half neighbour list whose contact history survives
//! re-neighbouring. Pairs are stored flat (CSR by first particle, second index
//! ascending) so the force pass is a parallel loop over independent pairs and the
//! history transfer after a rebuild is a linear merge.

use super::par::Shared;
use crate::numerics::vec3::V3;
use rayon::prelude::*;

/// Particles per block of the parallel candidate search.
const BUILD_BLOCK: usize = 256;

#[derive(Debug, Default, Clone)]
pub(crate) struct PairList {
    /// `start[i]..start[i+1]` are the pairs whose first particle is i.
    pub start: Vec<usize>,
    pub i: Vec<u32>,
    pub j: Vec<u32>,
    /// Tangential contact history of each pair (LIGGGHTS "shearx/y/z").
    pub shear: Vec<V3>,
    /// EPSD2 rolling history of each pair ("r_torquex_old"...); kept only when
    /// `track_roll` is set (empty otherwise: CDT and no rolling carry none).
    pub roll: Vec<V3>,
    pub track_roll: bool,
    /// For each particle, the slots of the pairs in which it is the second member (CSR
    /// again): `rev_start[p]..rev_start[p+1]`, slots in ascending pair order.
    pub rev_start: Vec<usize>,
    /// Slot of pair k in that reverse CSR.
    pub rev_pos: Vec<u32>,
    /// Positions at the last build, for the skin/2 displacement trigger.
    pub x_at_build: Vec<V3>,
    pub builds: u64,
    // Scratch buffers reused across builds so rebuilding does not allocate in steady state.
    cell_start: Vec<u32>,
    cell_items: Vec<u32>,
    new_start: Vec<usize>,
    new_i: Vec<u32>,
    new_j: Vec<u32>,
    new_shear: Vec<V3>,
    new_roll: Vec<V3>,
    cell_of: Vec<u32>,
    fill: Vec<usize>,
    /// Candidate pairs of each block of `BUILD_BLOCK` particles.
    block_pairs: Vec<Vec<u32>>,
}

/// A uniform grid over the domain box; cell edge >= the largest interaction cutoff.
#[derive(Debug, Clone, Copy)]
pub(super) struct Grid {
    lo: V3,
    inv: f64,
    n: [usize; 3],
}

impl Grid {
    pub(super) fn new(lo: V3, hi: V3, cutoff: f64) -> Grid {
        let mut n = [1usize; 3];
        for k in 0..3 {
            n[k] = (((hi[k] - lo[k]) / cutoff).floor() as usize).clamp(1, 1 << 20);
        }
        // Use the coarsest edge so every cell edge >= cutoff in all directions.
        let edge = (0..3)
            .map(|k| (hi[k] - lo[k]) / n[k] as f64)
            .fold(f64::INFINITY, f64::min);
        debug_assert!(edge >= cutoff * (1.0 - 1e-12));
        let _ = edge;
        Grid {
            lo,
            inv: 1.0 / cutoff,
            n,
        }
    }
    #[inline]
    pub(super) fn coord(&self, x: V3) -> [usize; 3] {
        let mut c = [0usize; 3];
        for k in 0..3 {
            let v = ((x[k] - self.lo[k]) * self.inv).floor();
            c[k] = (v.max(0.0) as usize).min(self.n[k] - 1);
        }
        c
    }
}

impl PairList {
    /// An empty list; `track_roll` keeps the EPSD2 rolling history per pair.
    pub(crate) fn with_roll(track_roll: bool) -> PairList {
        PairList {
            track_roll,
            ..PairList::default()
        }
    }

    /// Rebuilds the list for cutoff r_i + r_j + skin, carrying over the history of
    /// pairs that persist. The candidate search and the history merge run in parallel
    /// over blocks of particles; the list itself does not depend on the thread count
    /// (each particle's pairs are sorted by j).
    ///
    /// `body[i]` is the clump of particle i (-1: free sphere; an empty slice: all free).
    /// Two members of one clump are never listed: fix multisphere excludes them from
    /// the neighbour list (`neigh_modify exclude molecule`, neighbor.cpp:2174), and a
    /// pair that is not listed contributes nothing, exactly like a listed pair that
    /// never touches (the force sums skip it, its history stays zero).
    ///
    /// `old_of_new`: the particles were renumbered since the last build (a spatial sort,
    /// see [`super::reorder`]): new particle k was old particle `old_of_new[k]`. The
    /// history of a persisting pair is then looked up under its old numbers; a pair whose
    /// members swapped places (its first particle is now the one with the larger index)
    /// gets it negated, because shear and EPSD2 rolling history are the displacement and
    /// torque of the first particle relative to the second (LIGGGHTS flags both as
    /// negated for the partner in its contact history).
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        &mut self,
        x: &[V3],
        radius: &[f64],
        body: &[i32],
        skin: f64,
        lo: V3,
        hi: V3,
        old_of_new: Option<&[u32]>,
    ) {
        let n = x.len();
        assert!(body.is_empty() || body.len() == n);
        let rmax = radius.iter().cloned().fold(0.0, f64::max);
        let grid = Grid::new(lo, hi, 2.0 * rmax + skin);
        // One layer of empty cells around the grid, so every particle's 27 neighbour
        // cells exist and the stencil needs no bounds checks.
        let m = [grid.n[0] + 2, grid.n[1] + 2, grid.n[2] + 2];
        let ncell = m[0] * m[1] * m[2];
        let cell = |p: V3| {
            let c = grid.coord(p);
            ((c[2] + 1) * m[1] + c[1] + 1) * m[0] + c[0] + 1
        };

        // Counting sort of particles into cells.
        self.cell_start.clear();
        self.cell_start.resize(ncell + 1, 0);
        self.cell_of.clear();
        self.cell_of.extend(x.iter().map(|p| cell(*p) as u32));
        for &c in &self.cell_of {
            self.cell_start[c as usize + 1] += 1;
        }
        for c in 0..ncell {
            self.cell_start[c + 1] += self.cell_start[c];
        }
        self.cell_items.clear();
        self.cell_items.resize(n, 0);
        self.fill.clear();
        self.fill
            .extend(self.cell_start.iter().map(|&c| c as usize));
        for (p, &c) in self.cell_of.iter().enumerate() {
            self.cell_items[self.fill[c as usize]] = p as u32;
            self.fill[c as usize] += 1;
        }
        let (mx, my) = (m[0] as isize, m[1] as isize);
        let mut stencil = [0isize; 27];
        for (s, off) in stencil.iter_mut().enumerate() {
            let (dx, dy, dz) = (
                s as isize % 3 - 1,
                s as isize / 3 % 3 - 1,
                s as isize / 9 - 1,
            );
            *off = (dz * my + dy) * mx + dx;
        }

        // Candidates: per block of particles, each particle's j > i within the cutoff,
        // sorted, into the block's own buffer; `new_count[i]` pairs for particle i.
        let nb = n.div_ceil(BUILD_BLOCK);
        self.block_pairs.resize_with(nb, Vec::new);
        self.new_start.clear();
        self.new_start.resize(n + 1, 0);
        {
            let (cell_of, cell_start, cell_items) =
                (&self.cell_of, &self.cell_start, &self.cell_items);
            let counts = &mut self.new_start[1..];
            self.block_pairs
                .par_iter_mut()
                .zip(counts.par_chunks_mut(BUILD_BLOCK))
                .enumerate()
                .for_each(|(b, (buf, counts))| {
                    buf.clear();
                    for (l, count) in counts.iter_mut().enumerate() {
                        let i = b * BUILD_BLOCK + l;
                        let seg = buf.len();
                        let (xi, ri) = (x[i], radius[i]);
                        let bi = body.get(i).copied().unwrap_or(-1);
                        let ci = cell_of[i] as isize;
                        for off in stencil {
                            let c = (ci + off) as usize;
                            let items =
                                &cell_items[cell_start[c] as usize..cell_start[c + 1] as usize];
                            for &j in items {
                                let ju = j as usize;
                                if ju <= i || (bi >= 0 && body[ju] == bi) {
                                    continue;
                                }
                                let xj = x[ju];
                                let d = [xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]];
                                let cut = ri + radius[ju] + skin;
                                if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= cut * cut {
                                    buf.push(j);
                                }
                            }
                        }
                        buf[seg..].sort_unstable();
                        *count = buf.len() - seg;
                    }
                });
        }
        for i in 0..n {
            self.new_start[i + 1] += self.new_start[i];
        }
        let np = self.new_start[n];
        self.new_i.clear();
        self.new_i.resize(np, 0);
        self.new_j.clear();
        self.new_j.resize(np, 0);
        self.new_shear.clear();
        self.new_shear.resize(np, [0.0; 3]);
        self.new_roll.clear();
        if self.track_roll {
            self.new_roll.resize(np, [0.0; 3]);
        }

        // Per block: the pairs in place, and the history of pairs that touch now carried
        // over by merging the sorted old and new segments. LIGGGHTS 3.8 (neigh_gran.cpp)
        // does exactly this: a pair that separated keeps its stale shear until the next
        // rebuild, then loses it.
        let carry = self.start.len() == n + 1;
        let carry_roll = self.track_roll && self.roll.len() == self.shear.len();
        {
            let (new_start, block_pairs) = (&self.new_start, &self.block_pairs);
            let (old_start, old_j, old_shear, old_roll) =
                (&self.start, &self.j, &self.shear, &self.roll);
            let ni = Shared::new(&mut self.new_i);
            let nj = Shared::new(&mut self.new_j);
            let ns = Shared::new(&mut self.new_shear);
            let nr = Shared::new(&mut self.new_roll);
            (0..nb).into_par_iter().for_each(|b| {
                let r = b * BUILD_BLOCK..((b + 1) * BUILD_BLOCK).min(n);
                let kr = new_start[r.start]..new_start[r.end];
                let k0 = kr.start;
                // SAFETY: blocks own disjoint ranges of the new pair arrays.
                let (ni, nj, ns) = unsafe {
                    (
                        ni.slice(kr.clone()),
                        nj.slice(kr.clone()),
                        ns.slice(kr.clone()),
                    )
                };
                let nr: &mut [V3] = if carry_roll {
                    unsafe { nr.slice(kr.clone()) }
                } else {
                    &mut []
                };
                nj.copy_from_slice(&block_pairs[b]);
                for i in r {
                    let seg = new_start[i] - k0..new_start[i + 1] - k0;
                    ni[seg.clone()].fill(i as u32);
                    if !carry {
                        continue;
                    }
                    if let Some(old) = old_of_new {
                        for k in seg {
                            let ju = nj[k] as usize;
                            let d = [x[i][0] - x[ju][0], x[i][1] - x[ju][1], x[i][2] - x[ju][2]];
                            let radsum = radius[i] + radius[ju];
                            if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] >= radsum * radsum {
                                continue;
                            }
                            let (oi, oj) = (old[i], old[ju]);
                            let (first, second, sign) = if oi < oj {
                                (oi as usize, oj, 1.0)
                            } else {
                                (oj as usize, oi, -1.0)
                            };
                            let seg_old = old_start[first]..old_start[first + 1];
                            if let Some(a) = old_j[seg_old.clone()]
                                .iter()
                                .position(|&j| j == second)
                                .map(|p| seg_old.start + p)
                            {
                                let h = old_shear[a];
                                ns[k] = [sign * h[0], sign * h[1], sign * h[2]];
                                if carry_roll {
                                    let h = old_roll[a];
                                    nr[k] = [sign * h[0], sign * h[1], sign * h[2]];
                                }
                            }
                        }
                        continue;
                    }
                    let (mut a, a_end) = (old_start[i], old_start[i + 1]);
                    for k in seg {
                        let j = nj[k];
                        while a < a_end && old_j[a] < j {
                            a += 1;
                        }
                        if a < a_end && old_j[a] == j {
                            let ju = j as usize;
                            let d = [x[i][0] - x[ju][0], x[i][1] - x[ju][1], x[i][2] - x[ju][2]];
                            let radsum = radius[i] + radius[ju];
                            if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < radsum * radsum {
                                ns[k] = old_shear[a];
                                if carry_roll {
                                    nr[k] = old_roll[a];
                                }
                            }
                        }
                    }
                }
            });
        }
        std::mem::swap(&mut self.start, &mut self.new_start);
        std::mem::swap(&mut self.i, &mut self.new_i);
        std::mem::swap(&mut self.j, &mut self.new_j);
        std::mem::swap(&mut self.shear, &mut self.new_shear);
        std::mem::swap(&mut self.roll, &mut self.new_roll);

        // Reverse index: pairs in which a particle is the second member.
        self.rev_start.clear();
        self.rev_start.resize(n + 1, 0);
        for &j in &self.j {
            self.rev_start[j as usize + 1] += 1;
        }
        for p in 0..n {
            self.rev_start[p + 1] += self.rev_start[p];
        }
        self.rev_pos.clear();
        self.rev_pos.resize(self.j.len(), 0);
        self.fill.clear();
        self.fill.extend_from_slice(&self.rev_start);
        for (k, &j) in self.j.iter().enumerate() {
            self.rev_pos[k] = self.fill[j as usize] as u32;
            self.fill[j as usize] += 1;
        }

        self.x_at_build.clear();
        self.x_at_build.extend_from_slice(x);
        self.builds += 1;
    }

    pub fn len(&self) -> usize {
        self.j.len()
    }

    /// Bytes of every array of the list at its allocated capacity, scratch included.
    pub fn memory_bytes(&self) -> usize {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        b(&self.start)
            + b(&self.i)
            + b(&self.j)
            + b(&self.shear)
            + b(&self.roll)
            + b(&self.rev_start)
            + b(&self.rev_pos)
            + b(&self.x_at_build)
            + b(&self.cell_start)
            + b(&self.cell_items)
            + b(&self.new_start)
            + b(&self.new_i)
            + b(&self.new_j)
            + b(&self.new_shear)
            + b(&self.new_roll)
            + b(&self.cell_of)
            + b(&self.fill)
            + b(&self.block_pairs)
            + self.block_pairs.iter().map(b).sum::<usize>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_exactly_the_pairs_within_cutoff() {
        // Brute force vs cells on a random-ish cloud.
        let mut x = Vec::new();
        let mut s = 12345u64;
        let mut rnd = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..400 {
            x.push([rnd() * 0.02, rnd() * 0.02, rnd() * 0.02]);
        }
        let radius = vec![5e-4; x.len()];
        let mut l = PairList::default();
        l.build(&x, &radius, &[], 2e-4, [0.0; 3], [0.02; 3], None);
        let mut brute = 0;
        for i in 0..x.len() {
            for j in i + 1..x.len() {
                let d = crate::numerics::vec3::sub(x[i], x[j]);
                if crate::numerics::vec3::dot(d, d) < (1.2e-3f64).powi(2) {
                    brute += 1;
                }
            }
        }
        assert_eq!(l.len(), brute);
        assert!(
            brute > 50,
            "test cloud too sparse to mean anything: {brute}"
        );
    }

    #[test]
    fn history_survives_rebuild() {
        let x = vec![[0.0, 0.0, 0.0], [1.9e-3, 0.0, 0.0], [5e-3, 5e-3, 5e-3]];
        let radius = vec![1e-3; 3];
        let mut l = PairList::default();
        l.build(&x, &radius, &[], 5e-4, [-0.01; 3], [0.01; 3], None);
        assert_eq!(l.len(), 1);
        l.shear[0] = [1.0, 2.0, 3.0];
        let x2 = vec![[0.0, 0.0, 0.0], [1.9e-3, 1e-4, 0.0], [3.5e-3, 1.5e-3, 0.0]];
        l.build(&x2, &radius, &[], 5e-4, [-0.01; 3], [0.01; 3], None);
        let k = (l.start[0]..l.start[1])
            .find(|&k| l.j[k] == 1)
            .expect("pair 0-1 kept");
        assert_eq!(l.shear[k], [1.0, 2.0, 3.0]);
        assert!(l.shear.iter().filter(|h| **h != [0.0; 3]).count() == 1);
    }
}
