//! First pair of spheres overlapping by more than a fraction of the smaller radius,
//! found with a hash grid: O(N) memory whatever the packing, so an absurd case (1e6
//! grains in a millimetre box) is refused instead of exhausting memory.

use crate::numerics::vec3::{V3, dot, sub};
use std::collections::HashMap;

pub fn first_overlap(x: &[V3], r: &[f64], max_frac: f64) -> Option<(usize, usize, f64)> {
    let rmax = r.iter().copied().fold(0.0, f64::max);
    if x.len() < 2 || rmax <= 0.0 {
        return None;
    }
    let cell = 2.0 * rmax;
    let key = |p: &V3| -> [i64; 3] { std::array::from_fn(|c| (p[c] / cell).floor() as i64) };
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, p) in x.iter().enumerate() {
        let k = key(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let n = [k[0] + dx, k[1] + dy, k[2] + dz];
                    if let Some(others) = grid.get(&n) {
                        for &j in others {
                            let d = sub(x[i], x[j]);
                            let reach = r[i] + r[j];
                            let d2 = dot(d, d);
                            if d2 < reach * reach {
                                let overlap = reach - d2.sqrt();
                                if overlap > max_frac * r[i].min(r[j]) {
                                    return Some((j, i, overlap));
                                }
                            }
                        }
                    }
                }
            }
        }
        grid.entry(k).or_default().push(i);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_coincident_and_ignores_touching() {
        let x = [[0.0; 3], [2.0, 0.0, 0.0], [4.0, 0.0, 0.0], [4.0, 0.0, 0.0]];
        let r = [1.0; 4];
        assert_eq!(first_overlap(&x, &r, 0.05), Some((2, 3, 2.0)));
        assert_eq!(first_overlap(&x[..3], &r[..3], 0.05), None);
        // 4 % of the radius passes a 5 % limit, 6 % does not.
        let y = [[0.0; 3], [1.96, 0.0, 0.0]];
        assert_eq!(first_overlap(&y, &r[..2], 0.05), None);
        let z = [[0.0; 3], [1.94, 0.0, 0.0]];
        assert!(first_overlap(&z, &r[..2], 0.05).is_some());
    }
}
