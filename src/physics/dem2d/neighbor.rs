//! Linked cells + Verlet skin for disks, periodic in x. Pairs are kept sorted `(i, j)`
//! with `i < j`, so the shear history moves to the new list by a merge and the force
//! loop can run pairs in parallel yet sum them in one fixed order (results do not
//! depend on the number of threads).
//!
//! Disks much larger than the grains (a disk intruder of 10 d) would force cells of
//! 10 d; they are paired with every disk by brute force instead (O(N) per large disk).

/// The box in the plane; x is periodic with period `hi[0] - lo[0]` when `periodic_x`.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct Box2 {
    pub lo: [f64; 2],
    pub hi: [f64; 2],
    pub periodic_x: bool,
}

impl Box2 {
    pub(crate) fn len_x(&self) -> f64 {
        self.hi[0] - self.lo[0]
    }
    /// `a - b` with the minimum-image convention in x.
    #[inline]
    pub(crate) fn delta(&self, a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
        let mut dx = a[0] - b[0];
        if self.periodic_x {
            let l = self.len_x();
            if dx > 0.5 * l {
                dx -= l;
            } else if dx < -0.5 * l {
                dx += l;
            }
        }
        [dx, a[1] - b[1]]
    }
    /// Maps x back into `[lo, hi)` (LAMMPS remaps atoms the same way on re-neighbouring).
    #[inline]
    pub(crate) fn wrap(&self, mut x: [f64; 2]) -> [f64; 2] {
        if self.periodic_x {
            let l = self.len_x();
            while x[0] >= self.hi[0] {
                x[0] -= l;
            }
            while x[0] < self.lo[0] {
                x[0] += l;
            }
        }
        x
    }
}

/// Serialisable so that a settling run can stop and continue bit for bit
/// ([`super::Resume`]): the next rebuild reads `x_at_build`, and the shear of every
/// listed pair is contact history.
#[derive(Debug, Default, Clone, serde::Serialize, serde::Deserialize)]
pub struct PairList {
    pub pairs: Vec<(u32, u32)>,
    pub shear: Vec<[f64; 2]>,
    x_at_build: Vec<[f64; 2]>,
    pub builds: u64,
}

/// Which pairs may interact at all (frozen-frozen and intra-cluster pairs never do,
/// as with `neigh_modify exclude` in the LAMMPS deck).
pub trait Excluded: Sync {
    fn excluded(&self, i: usize, j: usize) -> bool;
}

impl PairList {
    /// True when some disk moved more than half the skin since the last build.
    pub(crate) fn needs_rebuild(
        &self,
        bx: &Box2,
        x: impl ExactSizeIterator<Item = [f64; 2]>,
        skin: f64,
    ) -> bool {
        if self.x_at_build.len() != x.len() {
            return true;
        }
        let lim = 0.25 * skin * skin;
        x.zip(&self.x_at_build).any(|(a, b)| {
            let d = bx.delta(a, *b);
            d[0] * d[0] + d[1] * d[1] > lim
        })
    }

    /// Rebuilds the list for interaction cutoff `r_i + r_j + skin`, keeping the shear
    /// of pairs present before and after.
    pub fn build(
        &mut self,
        bx: &Box2,
        x: &[[f64; 2]],
        radius: &[f64],
        skin: f64,
        ex: &dyn Excluded,
    ) {
        let n = x.len();
        let mut small_max = 0.0f64;
        let typical = {
            // The median (element n/2 in sorted order) by selection, O(n).
            let mut r: Vec<f64> = radius.to_vec();
            if n > 0 {
                *r.select_nth_unstable_by(n / 2, f64::total_cmp).1
            } else {
                0.0
            }
        };
        let large: Vec<bool> = radius.iter().map(|&r| r > 3.0 * typical).collect();
        for (k, &r) in radius.iter().enumerate() {
            if !large[k] {
                small_max = small_max.max(r);
            }
        }
        let cut = 2.0 * small_max + skin;
        let nx = ((bx.len_x() / cut).floor() as usize).max(1);
        let ymin = x
            .iter()
            .map(|p| p[1])
            .fold(f64::INFINITY, f64::min)
            .min(bx.lo[1]);
        let ymax = x
            .iter()
            .map(|p| p[1])
            .fold(f64::NEG_INFINITY, f64::max)
            .max(bx.hi[1]);
        let ny = (((ymax - ymin) / cut).floor() as usize).clamp(1, 1 << 22);
        let cx = bx.len_x() / nx as f64;
        let cy = (ymax - ymin) / ny as f64;
        let cell = |p: [f64; 2]| -> (usize, usize) {
            let ix = (((p[0] - bx.lo[0]) / cx).floor() as isize).clamp(0, nx as isize - 1) as usize;
            let iy = (((p[1] - ymin) / cy).floor() as isize).clamp(0, ny as isize - 1) as usize;
            (ix, iy)
        };
        // CSR cell lists.
        let mut count = vec![0usize; nx * ny + 1];
        let cells: Vec<(usize, usize)> = x.iter().map(|&p| cell(p)).collect();
        for (k, &(ix, iy)) in cells.iter().enumerate() {
            if !large[k] {
                count[iy * nx + ix + 1] += 1;
            }
        }
        for c in 1..count.len() {
            count[c] += count[c - 1];
        }
        let mut fill = count.clone();
        let mut items = vec![0u32; count[nx * ny]];
        for (k, &(ix, iy)) in cells.iter().enumerate() {
            if !large[k] {
                let c = iy * nx + ix;
                items[fill[c]] = k as u32;
                fill[c] += 1;
            }
        }
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        let push = |i: usize, j: usize, pairs: &mut Vec<(u32, u32)>| {
            if i == j || ex.excluded(i, j) {
                return;
            }
            let d = bx.delta(x[i], x[j]);
            let rc = radius[i] + radius[j] + skin;
            if d[0] * d[0] + d[1] * d[1] < rc * rc {
                let (a, b) = if i < j { (i, j) } else { (j, i) };
                pairs.push((a as u32, b as u32));
            }
        };
        for i in 0..n {
            if large[i] {
                continue;
            }
            let (ix, iy) = cells[i];
            for dy in -1isize..=1 {
                let jy = iy as isize + dy;
                if jy < 0 || jy >= ny as isize {
                    continue;
                }
                let mut seen = [usize::MAX; 3];
                for (s, dx) in (-1isize..=1).enumerate() {
                    let mut jx = ix as isize + dx;
                    if bx.periodic_x {
                        jx = jx.rem_euclid(nx as isize);
                    } else if jx < 0 || jx >= nx as isize {
                        continue;
                    }
                    // With fewer than 3 cells across, neighbours repeat; visit each once.
                    if seen.contains(&(jx as usize)) {
                        continue;
                    }
                    seen[s] = jx as usize;
                    let c = jy as usize * nx + jx as usize;
                    for &j in &items[count[c]..count[c + 1]] {
                        let j = j as usize;
                        if j > i {
                            push(i, j, &mut pairs);
                        }
                    }
                }
            }
        }
        for i in 0..n {
            if large[i] {
                for (j, &lj) in large.iter().enumerate() {
                    if !lj || j > i {
                        push(i, j, &mut pairs);
                    }
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        // Carry the shear over by merging two sorted lists.
        let mut shear = vec![[0.0; 2]; pairs.len()];
        let mut k_old = 0;
        for (k, p) in pairs.iter().enumerate() {
            while k_old < self.pairs.len() && self.pairs[k_old] < *p {
                k_old += 1;
            }
            if k_old < self.pairs.len() && self.pairs[k_old] == *p {
                shear[k] = self.shear[k_old];
            }
        }
        self.pairs = pairs;
        self.shear = shear;
        self.x_at_build = x.to_vec();
        self.builds += 1;
    }
}
